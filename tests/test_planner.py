"""MPPI planner: hand-worked weights, a fake model with a known optimum, scan == loop, one trace."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig, make_agent
from sirl_jax.agent.planner import PlannerModel, make_planner, mppi_update, run_mppi, warm_start

A = 3
TARGET = np.array([0.5, -0.3, 0.8], np.float32)
CFG = AgentConfig.tiny(num_samples=128, num_elites=16, num_pi_trajs=4, iterations=6)


def _fake_model(counter=None):
    """Latent = obs, static dynamics, reward -|a - target|^2, Q = 0, uniform random policy."""

    def encode(params, obs):
        if counter is not None:
            counter.append(1)  # runs once per trace
        return obs

    return PlannerModel(
        encode=encode,
        next=lambda p, z, a: z,
        reward=lambda p, z, a: -jnp.sum((a - p["target"]) ** 2, axis=-1),
        pi_sample=lambda p, z, k: jax.random.uniform(k, z.shape[:-1] + (A,), minval=-1, maxval=1),
        q_avg=lambda p, z, a, k: jnp.zeros(z.shape[:-1]),
    )


@pytest.mark.timeout(60)
def test_mppi_weights_by_hand():
    cfg = AgentConfig.tiny(num_samples=5, num_elites=2, num_pi_trajs=0, temperature=0.5)
    actions = jnp.arange(5.0).reshape(1, 5, 1)  # H=1, A=1, sample i has action i
    values = jnp.array([3.0, 1.0, 2.0, -4.0, jnp.nan])
    mean, std, elites, scores = mppi_update(cfg, values, actions)
    s = np.array([1.0, math.exp(-0.5)])
    s /= s.sum()
    np.testing.assert_allclose(scores, s, rtol=1e-6)
    np.testing.assert_allclose(elites[0, :, 0], [0.0, 2.0])
    m = s[0] * 0.0 + s[1] * 2.0
    assert float(mean[0, 0]) == pytest.approx(m, rel=1e-6)
    sd = math.sqrt(s[0] * m**2 + s[1] * (2.0 - m) ** 2)
    assert float(std[0, 0]) == pytest.approx(min(sd, cfg.max_std), rel=1e-5)
    # NaN -> 0 makes sample 4 (value 0) an elite ahead of sample 3 (value -4)
    _, _, el, _ = mppi_update(cfg, jnp.array([-1.0, -2.0, -3.0, -4.0, jnp.nan]), actions)
    np.testing.assert_allclose(el[0, :, 0], [4.0, 0.0])
    # +-inf -> the largest finite float of that sign (the reference's nan_to_num): +inf wins,
    # -inf loses to every finite value, and the scores stay finite.
    mean, std, el, sc = mppi_update(cfg, jnp.array([jnp.inf, 5.0, -jnp.inf, 1.0, 2.0]), actions)
    np.testing.assert_allclose(el[0, :, 0], [0.0, 1.0])
    assert np.all(np.isfinite(sc)) and np.isfinite(float(mean[0, 0]))
    _, _, el, _ = mppi_update(cfg, jnp.array([-jnp.inf, -5.0, -jnp.inf, -9.0, -7.0]), actions)
    np.testing.assert_allclose(el[0, :, 0], [1.0, 4.0])


@pytest.mark.timeout(60)
def test_warm_start_shift_and_reset():
    prev = jnp.arange(6.0).reshape(3, 2)
    np.testing.assert_allclose(warm_start(prev, jnp.array(False)), [[2, 3], [4, 5], [0, 0]])
    np.testing.assert_allclose(warm_start(prev, jnp.array(True)), 0.0)


def _ref_mppi(cfg, value_fn, mean, std, pi_actions, noise):
    """Plain numpy loop over iterations (independent of the scan implementation)."""
    mean, std = np.array(mean, np.float64), np.array(std, np.float64)
    for eps in np.asarray(noise, np.float64):
        sampled = np.clip(mean[:, None] + std[:, None] * eps, -1, 1)
        actions = np.concatenate([np.asarray(pi_actions, np.float64), sampled], axis=1)
        v = np.nan_to_num(value_fn(actions), nan=0.0)
        idx = np.argsort(-v, kind="stable")[: cfg.num_elites]
        el, ev = actions[:, idx], v[idx]
        s = np.exp(cfg.temperature * (ev - ev.max()))
        s /= s.sum()
        mean = np.einsum("k,hka->ha", s, el)
        std = np.clip(
            np.sqrt(np.einsum("k,hka->ha", s, (el - mean[:, None]) ** 2)), cfg.min_std, cfg.max_std
        )
    return mean, std


@pytest.mark.timeout(120)
def test_scan_equals_python_loop():
    cfg, H, N, P, iters = CFG, CFG.horizon, CFG.num_samples, CFG.num_pi_trajs, 5
    w = np.array([1.0, 0.7, 0.3])

    def value_np(actions):
        return -np.einsum("h,hn->n", w, ((actions - TARGET) ** 2).sum(-1))

    def value_jax(actions, key):
        return -jnp.einsum(
            "h,hn->n", jnp.asarray(w, jnp.float32), ((actions - TARGET) ** 2).sum(-1)
        )

    k1, k2 = jax.random.split(jax.random.PRNGKey(0))
    noise = jax.random.normal(k1, (iters, H, N - P, A))
    pi_actions = jax.random.uniform(k2, (H, P, A), minval=-1, maxval=1)
    mean0, std0 = jnp.full((H, A), 0.1), jnp.full((H, A), cfg.max_std)
    keys = jax.random.split(k2, iters)
    mean, std, _, _ = jax.jit(lambda *a: run_mppi(cfg, value_jax, *a))(
        mean0, std0, pi_actions, noise, keys
    )
    ref_mean, ref_std = _ref_mppi(cfg, value_np, mean0, std0, pi_actions, noise)
    np.testing.assert_allclose(mean, ref_mean, atol=1e-4)
    np.testing.assert_allclose(std, ref_std, atol=1e-4)


@pytest.mark.timeout(120)
def test_fake_model_moves_toward_optimum_and_compiles_once():
    traces = []
    planner = make_planner(CFG, A, 0.9, CFG.iterations, _fake_model(traces))
    plan = jax.jit(planner.plan, static_argnames="eval_mode")
    params = {"target": jnp.asarray(TARGET)}
    E = 4
    state = planner.init(E)
    errs = []
    for i in range(5):
        obs = jax.random.normal(jax.random.PRNGKey(i), (E, A))
        first = jnp.array([i == 0, False, i % 2 == 1, True])
        action, state = plan(params, state, obs, first, jax.random.PRNGKey(100 + i))
        errs.append(float(jnp.max(jnp.abs(state.prev_mean[:, 0] - TARGET))))
        assert action.shape == (E, A) and bool(jnp.all(jnp.abs(action) <= 1.0))
    assert len(traces) == 1
    # From mean 0 (error 0.8) every env's step-0 mean ends near the optimum.
    assert max(errs) < 0.15, errs
    a_eval, _ = plan(params, planner.init(E), obs, jnp.ones(E, bool), jax.random.PRNGKey(7), True)
    assert len(traces) == 2  # eval_mode is a separate static specialisation
    assert float(jnp.max(jnp.abs(a_eval - TARGET))) < 0.3


@pytest.mark.timeout(200)
def test_real_agent_plan_and_policy_shapes():
    agent = make_agent(AgentConfig.tiny(), obs_size=7, action_size=A, episode_length=100)
    state = jax.jit(agent.init)(jax.random.PRNGKey(0))
    pstate = agent.init_planner(2)
    obs = jax.random.normal(jax.random.PRNGKey(1), (2, 7))
    plan = jax.jit(agent.plan, static_argnames="eval_mode")
    action, pstate = plan(state, pstate, obs, jnp.array([True, False]), jax.random.PRNGKey(2))
    assert action.shape == (2, A) and pstate.prev_mean.shape == (2, CFG.horizon, A)
    assert bool(jnp.all(jnp.isfinite(action))) and bool(jnp.all(jnp.abs(action) <= 1.0))
    act = jax.jit(lambda s, o, k: (agent.act_policy(s, o, k, True), agent.act_policy(s, o, k)))
    a1, sample1 = act(state, obs, jax.random.PRNGKey(3))
    a2, _ = act(state, obs, jax.random.PRNGKey(4))
    np.testing.assert_array_equal(a1, a2)  # eval: tanh(mu), no sampling
    assert not np.allclose(sample1, a1)


@pytest.mark.timeout(120)
def test_env_chunked_map_equals_vmap():
    params = {"target": jnp.asarray(TARGET)}
    obs = jax.random.normal(jax.random.PRNGKey(0), (4, A))
    first = jnp.array([True, False, True, False])
    out = []
    for chunk in (0, 2):
        cfg = AgentConfig.tiny(num_samples=64, num_elites=8)
        planner = make_planner(cfg, A, 0.9, 2, _fake_model(), env_chunk=chunk)
        state = planner.init(4)
        state = state.replace(prev_mean=jnp.full_like(state.prev_mean, 0.2))
        out.append(jax.jit(planner.plan)(params, state, obs, first, jax.random.PRNGKey(1)))
    np.testing.assert_allclose(out[0][0], out[1][0], atol=1e-6)
    np.testing.assert_allclose(out[0][1].prev_mean, out[1][1].prev_mean, atol=1e-6)
