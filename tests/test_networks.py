"""Network blocks, initialisation and parameter counts (spec §1)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig
from sirl_jax.agent.networks import NormedLinear, count_params, init_params, simnorm
from sirl_jax.agent.world_model import make_world_model

# Spec §1.6, "our count" columns: (size) -> (h1hand obs 151 / A 61, h1 obs 51 / A 19), millions.
SPEC_COUNTS = {
    "1M": (1.37, 1.25),
    "5M": (5.25, 5.03),
    "19M": (18.7, 18.2),
    "48M": (48.3, 47.5),
    "317M": (315.8, 313.3),
}


def _init(cfg, obs=20, act=6):
    """Jitted init (one compile instead of one per eager op)."""
    return jax.jit(lambda k: init_params(cfg, obs, act, k))(jax.random.PRNGKey(0))


@pytest.mark.timeout(120)
@pytest.mark.parametrize("size", list(SPEC_COUNTS))
def test_param_counts_match_spec(size):
    cfg = AgentConfig(model_size=size)
    for (obs, act), want in zip(((151, 61), (51, 19)), SPEC_COUNTS[size], strict=True):
        shapes = jax.eval_shape(
            lambda k, o=obs, a=act: init_params(cfg, o, a, k), jax.random.PRNGKey(0)
        )
        got = count_params(shapes) / 1e6
        assert abs(got - want) / want < 0.01, (size, obs, act, got, want)
        if size == "5M" and act == 61:
            assert abs(count_params(shapes["qs"]) / 1e6 - 3.05) / 3.05 < 0.01


@pytest.mark.timeout(60)
def test_simnorm_groups_sum_to_one():
    x = jax.random.normal(jax.random.PRNGKey(0), (3, 64)) * 5
    y = simnorm(x, 8).reshape(3, 8, 8)
    np.testing.assert_allclose(y.sum(-1), 1.0, atol=1e-6)
    assert bool(jnp.all(y >= 0))


@pytest.mark.timeout(60)
def test_normed_linear_matches_manual():
    layer = NormedLinear(4)
    x = jnp.array([[0.3, -1.2, 2.0]])
    p = layer.init(jax.random.PRNGKey(1), x)["params"]
    h = np.asarray(x @ p["Dense_0"]["kernel"] + p["Dense_0"]["bias"], np.float64)
    h = (h - h.mean()) / np.sqrt(h.var() + 1e-5)  # LayerNorm eps 1e-5, weight 1, bias 0
    want = h * np.tanh(np.log1p(np.exp(h)))  # Mish
    np.testing.assert_allclose(layer.apply({"params": p}, x), want, rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(p["LayerNorm_0"]["scale"], 1.0)


@pytest.mark.timeout(120)
def test_init_statistics_and_zero_heads():
    cfg = AgentConfig.tiny(mlp_dim=256)
    params = _init(cfg)
    k = params["dynamics"]["NormedLinear_0"]["Dense_0"]["kernel"]
    assert float(jnp.std(k)) == pytest.approx(0.02, rel=0.05)
    np.testing.assert_array_equal(params["dynamics"]["NormedLinear_0"]["Dense_0"]["bias"], 0.0)
    np.testing.assert_array_equal(params["reward"]["Dense_0"]["kernel"], 0.0)
    np.testing.assert_array_equal(params["qs"]["Dense_0"]["kernel"], 0.0)
    assert float(jnp.std(params["policy"]["Dense_0"]["kernel"])) > 0.01  # policy head not zeroed
    assert params["qs"]["Dense_0"]["kernel"].shape[0] == cfg.arch.num_q
    # Q members are initialised independently.
    q0 = params["qs"]["NormedLinear_0"]["Dense_0"]["kernel"]
    assert not np.allclose(q0[0], q0[1])
    wm = make_world_model(cfg, 6)
    z = jax.random.uniform(jax.random.PRNGKey(2), (5, 32))
    a = jnp.zeros((5, 6))
    r, q = jax.jit(
        lambda p: (wm.reward(p, z, a), wm.q_pair(p["qs"], z, a, jax.random.PRNGKey(3), "avg"))
    )(params)
    # Uniform softmax over symmetric bins: 0 up to float32 rounding of the bin centres.
    np.testing.assert_allclose(r, 0.0, atol=1e-5)
    np.testing.assert_allclose(q, 0.0, atol=1e-5)


@pytest.mark.timeout(120)
def test_policy_bounds_and_log_prob():
    cfg = AgentConfig.tiny()
    params = _init(cfg)
    params["policy"]["Dense_0"]["bias"] = (
        params["policy"]["Dense_0"]["bias"]
        .at[6:]
        .set(jnp.array([-50.0, 50.0, 0.0, 0.3, -0.3, 1.0]))
    )
    wm = make_world_model(cfg, 6)
    z = jnp.zeros((1, 32))
    out = jax.jit(wm.pi)(params, z, jax.random.PRNGKey(4))
    assert float(out.log_std.min()) >= -10.0 and float(out.log_std.max()) <= 2.0
    np.testing.assert_allclose(out.log_std[0, :3], [-10.0, 2.0, -4.0], atol=1e-4)
    eps, ls = np.asarray(out.eps[0], np.float64), np.asarray(out.log_std[0], np.float64)
    lp_g = np.sum(-0.5 * eps**2 - ls) - 3 * math.log(2 * math.pi)
    assert float(out.log_prob_gauss[0]) == pytest.approx(lp_g, rel=1e-5)
    a = np.tanh(np.asarray(out.mu[0]) + np.exp(ls) * eps)
    np.testing.assert_allclose(out.action[0], a, atol=1e-5)
    lp_s = lp_g - np.sum(np.log(np.maximum(0, 1 - a**2) + 1e-6))
    assert float(out.log_prob[0]) == pytest.approx(lp_s, rel=1e-4)


@pytest.mark.timeout(120)
def test_q_dropout_independent_per_member():
    cfg = AgentConfig.tiny(dropout=0.5)
    params = _init(cfg)
    # Give every member identical, non-zero weights: only dropout can make them differ.
    qs = jax.tree_util.tree_map(lambda p: jnp.broadcast_to(p[:1] + 0.1, p.shape), params["qs"])
    wm = make_world_model(cfg, 6)
    z, a = jnp.ones((4, 32)), jnp.ones((4, 6))
    det, drop = jax.jit(
        lambda q: (wm.q_logits(q, z, a, None), wm.q_logits(q, z, a, jax.random.PRNGKey(1)))
    )(qs)
    np.testing.assert_allclose(det[0], det[1], atol=1e-6)
    assert not np.allclose(drop[0], drop[1])
