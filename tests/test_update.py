"""Losses and the update step: hand-worked values, the SIRL weight, and beta=0 == TD-MPC2."""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.agent import losses as L
from sirl_jax.agent.agent import polyak
from sirl_jax.agent.hyper import with_hyper
from sirl_jax.agent.networks import init_params
from sirl_jax.agent.world_model import make_world_model
from sirl_jax.types import Batch

R_MAX = jnp.array(100.0)  # the buffer R_max the updates receive (G = R_max)
O, A, T, H, B = 10, 4, 100, 3, 8
BASE = AgentConfig.tiny()


def _cfg(**sirl):
    return dataclasses.replace(BASE, sirl=SirlConfig(**sirl))


def _batch(key):
    k1, k2, k3 = jax.random.split(key, 3)
    return Batch(
        obs=jax.random.normal(k1, (H + 1, B, O)),
        action=jnp.tanh(jax.random.normal(k2, (H, B, A))),
        reward=jax.random.uniform(k3, (H, B), minval=-1.0, maxval=3.0),
        terminated=jnp.zeros((H, B)),
        episode_return=jnp.linspace(-50.0, 150.0, B),
    )


@pytest.fixture(scope="module")
def setup():
    """Jitted updates for beta=1, beta=0 and the plain TD-MPC2 path, sharing init state."""
    agents = {
        "beta1": make_agent(_cfg(), O, A, T),
        "beta0": make_agent(_cfg(beta=0.0), O, A, T),
        "plain": make_agent(_cfg(enabled=False), O, A, T),
    }
    state = jax.jit(agents["beta1"].init)(jax.random.PRNGKey(0))
    # each agent's update reads beta from the state (`state.hyper`): give it its own
    updates = {k: jax.jit(lambda s, *xs, a=a: a.update(with_hyper(s, a.cfg), *xs))
               for k, a in agents.items()}  # fmt: skip
    return agents, updates, state, _batch(jax.random.PRNGKey(1))


@pytest.mark.timeout(240)
def test_first_update_hand_values(setup):
    agents, updates, state, batch = setup
    new, m = updates["beta1"](state, batch, R_MAX, jax.random.PRNGKey(2))
    rho_sum = 1 + 0.5 + 0.25
    # Zero-initialised heads: uniform logits, so each CE is ln(101); rho-weighted mean over H.
    assert float(m["reward_loss"]) == pytest.approx(math.log(101) * rho_sum / H, rel=1e-5)
    assert float(m["value_loss"]) == pytest.approx(math.log(101) * rho_sum / H, rel=1e-5)
    # Target Qs decode to 0 at init, so y = r.
    assert float(m["td_target_mean"]) == pytest.approx(float(batch.reward.mean()), abs=1e-4)
    # Online Qs are 0 at init: P95 - P5 = 0 -> S = 1 + 0.01 * (max(1, 0) - 1) = 1.
    assert float(m["pi_scale"]) == pytest.approx(1.0)
    R = np.linspace(-50.0, 150.0, B)
    omega = np.exp(np.minimum((R - 100.0) / 100.0, 0.0))
    assert float(m["sirl_weight_mean"]) == pytest.approx(omega.mean(), rel=1e-5)
    want = {
        "consistency_loss",
        "reward_loss",
        "value_loss",
        "pi_loss",
        "sirl_loss",
        "sirl_weight_mean",
        "total_loss",
        "grad_norm",
        "pi_grad_norm",
        "pi_scale",
        "pi_entropy",
        "pi_log_std",
        "termination_loss",
    }
    assert want <= set(m)
    assert float(m["termination_loss"]) == 0.0  # not episodic: no head, metric kept at 0
    assert all(v.shape == () and bool(jnp.isfinite(v)) for v in m.values())
    # Polyak: target <- 0.99 target + 0.01 online (updated) Qs, on Q params only.
    want_t = polyak(state.target_qs, new.params["qs"], 0.01)
    for a, b in zip(
        jax.tree_util.tree_leaves(new.target_qs), jax.tree_util.tree_leaves(want_t), strict=True
    ):
        np.testing.assert_allclose(a, b, atol=1e-7)


@pytest.mark.timeout(240)
def test_beta_zero_equals_plain_tdmpc2(setup):
    _, updates, state, batch = setup
    s0, s1 = state, state
    for i in range(3):
        key = jax.random.PRNGKey(10 + i)
        s0, m0 = updates["beta0"](s0, batch, R_MAX, key)
        s1, m1 = updates["plain"](s1, batch, R_MAX, key)
    assert float(s0.hyper["sirl_beta"]) == 0.0 and float(s1.hyper["sirl_beta"]) == 1.0
    s0 = s0.replace(hyper=s1.hyper)  # the configs' betas; the term is off in "plain"
    for a, b in zip(jax.tree_util.tree_leaves(s0), jax.tree_util.tree_leaves(s1), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6)
    for k in m1:
        np.testing.assert_allclose(m0[k], m1[k], rtol=1e-6, atol=1e-6, err_msg=k)
    assert float(m0["sirl_weight_mean"]) == 0.0 and float(m0["sirl_loss"]) == 0.0


@pytest.mark.timeout(240)
def test_bc_term_changes_only_the_policy(setup):
    _, updates, state, batch = setup
    key = jax.random.PRNGKey(3)
    s1, m1 = updates["beta1"](state, batch, R_MAX, key)
    s0, _ = updates["beta0"](state, batch, R_MAX, key)
    for name in ("encoder", "dynamics", "reward", "qs"):
        for a, b in zip(
            jax.tree_util.tree_leaves(s1.params[name]),
            jax.tree_util.tree_leaves(s0.params[name]),
            strict=True,
        ):
            np.testing.assert_array_equal(a, b)
    diff = jax.tree_util.tree_map(
        lambda a, b: jnp.max(jnp.abs(a - b)), s1.params["policy"], s0.params["policy"]
    )
    assert max(float(x) for x in jax.tree_util.tree_leaves(diff)) > 1e-5
    assert float(m1["sirl_loss"]) > 0


@pytest.mark.timeout(240)
def test_updates_reduce_world_model_loss(setup):
    _, updates, state, batch = setup
    s, first = state, None
    for i in range(40):
        s, m = updates["beta1"](s, batch, R_MAX, jax.random.PRNGKey(100 + i))
        first = m if first is None else first
    assert float(m["reward_loss"]) < float(first["reward_loss"]) - 0.1
    assert float(m["wm_loss"]) < float(first["wm_loss"])
    assert all(bool(jnp.isfinite(v)) for v in m.values())


@pytest.mark.timeout(60)
def test_td_target_and_polyak_by_hand():
    r, q, d = jnp.array([1.0, 2.0]), jnp.array([10.0, 20.0]), jnp.array([0.0, 1.0])
    np.testing.assert_allclose(L.td_target(r, q, d, 0.9, True), [10.0, 2.0])
    np.testing.assert_allclose(L.td_target(r, q, d, 0.9, False), [10.0, 20.0])
    out = polyak({"w": jnp.zeros(3)}, {"w": jnp.array([1.0, 2.0, -3.0])}, 0.01)
    np.testing.assert_allclose(out["w"], [0.01, 0.02, -0.03], rtol=1e-6)


@pytest.mark.timeout(60)
def test_running_scale_matches_numpy_percentile():
    q0 = np.random.default_rng(0).normal(size=37).astype(np.float32) * 7
    p5, p95 = np.percentile(q0, [5, 95], method="linear")
    want = 2.0 + 0.01 * (max(1.0, p95 - p5) - 2.0)
    assert float(L.update_scale(jnp.array(2.0), jnp.asarray(q0), 0.01)) == pytest.approx(want)
    # Narrow spread: the floor of 1 applies.
    assert float(L.update_scale(jnp.array(1.0), jnp.full(8, 3.0), 0.01)) == pytest.approx(1.0)


@pytest.mark.timeout(60)
def test_sirl_weight_values():
    s = SirlConfig()
    w = lambda R, G, cfg=s: float(L.sirl_weight(jnp.array(R), jnp.array(G), cfg))
    assert w(50.0, 100.0) == pytest.approx(math.exp(-0.5))
    assert w(100.0, 100.0) == pytest.approx(1.0)
    assert w(150.0, 100.0) == pytest.approx(1.0)  # R > G: exponent clipped to 0
    assert w(-150.0, -100.0) == pytest.approx(math.exp(-0.5))  # G < 0: |G| denominator
    assert w(-50.0, -100.0) == pytest.approx(1.0)
    assert w(-1.0, 0.0) == pytest.approx(math.exp(-1000.0))  # G = 0: floor g_eps = 1e-3
    assert w(50.0, 100.0, SirlConfig(beta=2.0)) == pytest.approx(2 * math.exp(-0.5))
    assert w(150.0, 100.0, SirlConfig(clip_exponent=False)) == pytest.approx(math.exp(0.5))


@pytest.mark.timeout(120)
def test_bc_loglik_by_hand_and_per_dimension_scale():
    cfg = BASE
    wm = make_world_model(cfg, A)
    z = jax.random.uniform(jax.random.PRNGKey(6), (2, 32))
    act = jnp.array([[0.3, -0.9, 0.0, 1.0], [-1.0, 0.5, 0.99, -0.2]])
    omega = jnp.array([0.5, 1.0])
    mse = {
        f: dataclasses.replace(cfg, sirl=SirlConfig(bc_form=f)) for f in ("mse_mean", "mse_sample")
    }

    @jax.jit
    def run(key):
        params = init_params(cfg, O, A, key)
        out = wm.pi(params, z, jax.random.PRNGKey(7))
        out2 = jax.tree_util.tree_map(lambda v: jnp.stack([v, v]), out)  # [H+1=2, ...]
        loglik, _ = wm.pi_log_prob(params, z, act)
        bc = {"loglik": L.bc_term(cfg, out2, act[None], omega)}
        for f, c in mse.items():
            bc[f] = L.bc_term(c, out2, act[None], omega)
        return out, loglik, bc

    out, got, bc = run(jax.random.PRNGKey(5))
    mu, ls = np.asarray(out.mu, np.float64), np.asarray(out.log_std, np.float64)
    a = np.clip(np.asarray(act, np.float64), -1 + 1e-6, 1 - 1e-6)
    x = (np.arctanh(a) - mu) / np.exp(ls)
    ll = np.sum(-0.5 * x**2 - ls - 0.5 * math.log(2 * math.pi) - np.log(1 - a**2 + 1e-6), -1)
    np.testing.assert_allclose(got, ll, rtol=2e-3)
    # loglik form: -omega * log pi / A (mean over action dimensions).
    np.testing.assert_allclose(bc["loglik"][0], -np.array([0.5, 1.0]) * ll / A, rtol=2e-3)
    # mse forms: omega * mean over action dims.
    for form, ref in (("mse_mean", out.mean_action), ("mse_sample", out.action)):
        want = np.array([0.5, 1.0]) * np.mean((np.asarray(ref) - np.asarray(act)) ** 2, -1)
        np.testing.assert_allclose(bc[form][0], want, rtol=1e-5)


@pytest.mark.timeout(120)
def test_bc_reduce_sum_and_mean_by_hand():
    """A hand-made policy output: mu = 0, log sigma = 0 on A = 2 dims, so per dimension
    -log pi_i(a_i) = 0.5 atanh(a_i)^2 + 0.5 log(2 pi) + log(1 - a_i^2 + 1e-6)."""
    from sirl_jax.agent.world_model import PolicyOutput

    a = np.array([[0.5, -0.25]])  # [B=1, A=2]
    per_dim = 0.5 * np.arctanh(a) ** 2 + 0.5 * math.log(2 * math.pi) + np.log(1 - a**2 + 1e-6)
    zeros = jnp.zeros((2, 1, 2))  # [H+1=2, B, A]
    out = PolicyOutput(zeros, zeros, zeros, zeros, zeros, jnp.zeros((2, 1)), jnp.zeros((2, 1)))
    omega = jnp.array([0.5])
    for reduce, want in (("mean", per_dim.mean(-1)), ("sum", per_dim.sum(-1))):
        cfg = dataclasses.replace(BASE, sirl=SirlConfig(bc_reduce=reduce))
        got = L.bc_term(cfg, out, jnp.asarray(a)[None], omega)
        np.testing.assert_allclose(got[0], 0.5 * want, rtol=1e-5)
    # The mse forms reduce the same way: squared errors (0.5^2, 0.25^2) to tanh(mu) = 0.
    cfg = dataclasses.replace(BASE, sirl=SirlConfig(bc_form="mse_mean", bc_reduce="sum"))
    got = L.bc_term(cfg, out, jnp.asarray(a)[None], omega)
    np.testing.assert_allclose(got[0], 0.5 * (0.25 + 0.0625), rtol=1e-6)
    with pytest.raises(ValueError, match="bc_reduce"):
        SirlConfig(bc_reduce="max")


@pytest.mark.timeout(60)
def test_clamped_fraction_on_a_hand_made_batch():
    # 12 components: 4 exactly at the clamp (+-1), 2 more within 1e-6 of it, 1 within 2e-3.
    acts = jnp.array([[[1.0, -1.0, 0.3], [0.0, 1.0 - 1e-7, -0.5]],
                      [[-1.0, 0.999, 0.2], [1.0, 0.1, -0.999999]]])  # fmt: skip
    assert float(L.clamped_fraction(acts, 1e-6)) == pytest.approx(6 / 12)
    assert float(L.clamped_fraction(acts, 1e-8)) == pytest.approx(4 / 12)
    assert float(L.clamped_fraction(acts, 2e-3)) == pytest.approx(7 / 12)
    with pytest.raises(ValueError, match="action_clip"):
        SirlConfig(action_clip=0.0)
