"""FastTD3 (`agent.kind="fasttd3"`): its parts by hand, the self-imitative term, and the shared
train step (one compile, seeds vmapped, resume bit-identical, eval, export) on the pendulum."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.agent.fasttd3 import ObsNorm, project
from sirl_jax.agent.fasttd3_config import FastTD3Config
from sirl_jax.agent.hyper import with_hyper
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs.classic import PendulumSwingup
from sirl_jax.presets import get_preset
from sirl_jax.train import make_train
from sirl_jax.types import Batch

O, A, B, P = 5, 2, 16, 2


def _agent(beta: float = 1.0, enabled: bool = True, **fields):
    base = dict(actor_hidden_dim=16, critic_hidden_dim=32, num_atoms=11, batch_size=B,
                v_min=-10.0, v_max=10.0)  # fmt: skip
    cfg = AgentConfig(kind="fasttd3", fasttd3=FastTD3Config(**{**base, **fields}),
                      sirl=SirlConfig(enabled=enabled, beta=beta, bc_form="mse_mean"))  # fmt: skip
    return make_agent(cfg, O, A, episode_length=100)


def _batch(key, n: int = 1, rows: int = P * B) -> Batch:
    k = jax.random.split(key, 5)
    return Batch(
        obs=jax.random.normal(k[0], (n + 1, rows, O)) * 3.0 + 1.0,
        action=jax.random.uniform(k[1], (n, rows, A), minval=-1.0, maxval=1.0),
        reward=jax.random.uniform(k[2], (n, rows)),
        terminated=(jax.random.uniform(k[3], (n, rows)) < 0.2).astype(jnp.float32),
        episode_return=jax.random.uniform(k[4], (rows,), minval=0.0, maxval=50.0),
    )


def test_projection_by_hand():
    # Support -2..2 in steps of 1 (index = value + 2).
    support = jnp.linspace(-2.0, 2.0, 5)
    probs = jnp.eye(5)  # row i: all mass on atom i
    out = np.asarray(project(probs, jnp.full(5, 0.5), jnp.ones(5), 1.0, support, -2.0, 2.0))
    expected = np.zeros((5, 5))
    # atom z -> z + 0.5: -2 -> -1.5 (indices 0, 1 half each), ..., 1 -> 1.5 (3, 4), 2 -> 2.5
    # clipped to 2 (index 4).
    for i in range(4):
        expected[i, i] = expected[i, i + 1] = 0.5
    expected[4, 4] = 1.0
    np.testing.assert_allclose(out, expected, atol=1e-6)
    # A terminal step ignores z: all mass at r = 1 exactly (index 3), from every atom.
    out = np.asarray(project(probs, jnp.ones(5), jnp.zeros(5), 1.0, support, -2.0, 2.0))
    np.testing.assert_allclose(out, np.tile([0, 0, 0, 1.0, 0], (5, 1)), atol=1e-6)
    # gamma 0.5, r = -0.25: z = 1 (mass 0.4) -> 0.25, index 2.25: 0.75 to 2, 0.25 to 3;
    # z = 2 (mass 0.6) -> 0.75, index 2.75: 0.25 to 2, 0.75 to 3.
    p = jnp.array([[0.0, 0.0, 0.0, 0.4, 0.6]])
    out = np.asarray(project(p, jnp.array([-0.25]), jnp.ones(1), 0.5, support, -2.0, 2.0))
    np.testing.assert_allclose(out, [[0, 0, 0.4 * 0.75 + 0.6 * 0.25, 0.4 * 0.25 + 0.6 * 0.75, 0]],
                               atol=1e-6)  # fmt: skip


def test_obs_norm_follows_fasttd3s_running_update():
    """FastTD3's EmpiricalNormalization: the mean is exact; the variance update adds the
    between-batch term with the *updated* mean (delta2 in its code), so it is close to, not
    equal to, the sample variance. Expected values by a plain loop over that rule."""
    x = np.random.default_rng(0).normal(2.0, 3.0, (70, 4)).astype(np.float64)
    mean, var, count = np.zeros(4), np.ones(4), 0
    for chunk in (x[:30], x[30:]):
        n, bm, bv = len(chunk), chunk.mean(0), chunk.var(0)
        new = count + n
        mean = mean + (bm - mean) * n / new
        var = (var * count + bv * n + (bm - mean) ** 2 * count * n / new) / new
        count = new
    norm = ObsNorm.init(4).update(jnp.asarray(x[:30])).update(jnp.asarray(x[30:]))
    np.testing.assert_allclose(norm.mean, x.mean(0), rtol=1e-5)
    np.testing.assert_allclose(norm.var, var, rtol=1e-5)
    np.testing.assert_allclose(norm.var, x.var(0), rtol=0.1)
    assert float(norm.count) == 70
    np.testing.assert_allclose(norm(jnp.asarray(x[:1]), 0.01),
                               (x[:1] - mean) / (np.sqrt(var) + 0.01), rtol=1e-5)  # fmt: skip


@pytest.mark.timeout(300)
def test_beta_zero_is_plain_fasttd3_and_the_term_is_as_defined():
    key, batch = jax.random.PRNGKey(0), _batch(jax.random.PRNGKey(1))
    r_max = jnp.float32(40.0)
    plain, zero, sirl = _agent(enabled=False), _agent(beta=0.0), _agent(beta=1.0)
    state = plain.init(key)
    s_plain, m_plain = jax.jit(plain.update)(state, batch, r_max, key)
    # the update reads beta from the state (`state.hyper`): each agent gets its own
    s_zero, m_zero = jax.jit(zero.update)(with_hyper(state, zero.cfg), batch, r_max, key)
    assert float(s_zero.hyper["sirl_beta"]) == 0.0
    jax.tree.map(lambda x, y: np.testing.assert_array_equal(x, y), s_plain,
                 s_zero.replace(hyper=s_plain.hyper))  # fmt: skip
    assert float(m_zero["sirl_loss"]) == 0.0 and float(m_plain["sirl_loss"]) == 0.0

    # beta 1: the critics see the same data, the actor gets sg(S) * mean(omega * BC) on top.
    s_sirl, m_sirl = jax.jit(sirl.update)(with_hyper(state, sirl.cfg), batch, r_max, key)
    jax.tree.map(lambda x, y: np.testing.assert_array_equal(x, y),
                 s_plain.params["critic"], s_sirl.params["critic"])  # fmt: skip
    assert not np.allclose(s_plain.params["actor"]["out"]["kernel"],
                           s_sirl.params["actor"]["out"]["kernel"])  # fmt: skip
    # By hand on the last group's batch, normalised with the statistics of all four updates
    # (s_0 then s_n of each group) up to that batch's s_0.
    last = jax.tree.map(lambda x: x[..., B:, :] if x.ndim == 3 else x[..., B:], batch)
    norm = ObsNorm.init(O)
    for rows in (batch.obs[0, :B], batch.obs[1, :B], batch.obs[0, B:]):
        norm = norm.update(rows)  # checked against FastTD3's rule above
    s0 = np.asarray(norm(last.obs[0], 0.01))
    from sirl_jax.agent.fasttd3 import ReluMLP

    # The actor loss reads the actor before its update: the initial one.
    pi = ReluMLP((16, 8, 4), A, 0.01, tanh=True).apply({"params": state.params["actor"]}, s0)
    bc = np.mean((np.asarray(pi) - np.asarray(last.action[0])) ** 2, axis=-1)
    omega = np.exp(np.minimum((np.asarray(last.episode_return) - 40.0) / 40.0, 0.0))
    expected = float(m_sirl["pi_scale"]) * np.mean(omega * bc)
    np.testing.assert_allclose(float(m_sirl["sirl_loss"]), expected, rtol=2e-4)
    np.testing.assert_allclose(float(m_sirl["sirl_weight_mean"]), omega.mean(), rtol=1e-5)


def test_deterministic_actor_refuses_a_likelihood_bc():
    with pytest.raises(ValueError, match="sirl.bc_form='loglik'.*mse_mean"):
        AgentConfig(kind="fasttd3")
    with pytest.raises(ValueError, match="kind='ppo'"):
        AgentConfig(kind="ppo")
    with pytest.raises(ValueError, match="fasttd3.v_min"):
        FastTD3Config(v_min=5.0, v_max=1.0)


# --- the shared train step on the pendulum -------------------------------------------------

E, K, T = 2, 25, 50


def _config(**train) -> Config:
    agent = dataclasses.replace(
        get_preset("fasttd3-smoke").agent,
        fasttd3=FastTD3Config(actor_hidden_dim=16, critic_hidden_dim=32, num_atoms=11,
                              batch_size=8, v_min=-60.0, v_max=60.0),
    )  # fmt: skip
    base = dict(task="pendulum", steps=1_000, num_envs=E, chunk_steps=K, seed_steps=50,
                buffer_size=1_000, eval_episodes=2)  # fmt: skip
    return Config(agent=agent, train=TrainConfig(**{**base, **train}))


@pytest.mark.slow  # 1.9 min: two fused-step compiles (vmapped and single)
@pytest.mark.timeout(420)
def test_train_step_compiles_once_and_vmapped_seeds_equal_single_runs():
    train = make_train(_config(), PendulumSwingup(episode_length=T))
    assert train.pretrain_updates == 0 and train.updates_per_step == 1.0
    traces = []

    def counted(state):
        traces.append(1)
        return train.step(state)

    init, step = jax.jit(train.init), jax.jit(counted)
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    singles = []
    for s in range(2):
        state, hist = init(keys[s]), []
        for _ in range(3):
            state, metrics = step(state)
            hist.append(jax.device_get((state.agent.params, state.buffer.obs, metrics)))
        singles.append(hist)
    assert len(traces) == 1, "the train step must compile once"
    # The first episodes end at chunk 2's last step (T = 50 vectorised steps): acting starts
    # there, without pretraining, and chunk 3 runs one update group per vectorised step.
    ups = [int(m["updates"]) for _, _, m in singles[0]]
    assert ups == [0, 0, K]
    for name, v in singles[0][-1][2].items():
        if name.startswith("train/"):
            assert np.isfinite(v), name
    vstate = jax.jit(jax.vmap(train.init))(keys)
    vstep = jax.jit(jax.vmap(train.step))
    for chunk in range(3):
        vstate, vmetrics = vstep(vstate)
        batched = jax.device_get((vstate.agent.params, vstate.buffer.obs, vmetrics))
        for s in range(2):
            jax.tree.map(lambda x, y, s=s: np.testing.assert_allclose(x[s], y, rtol=1e-4,
                                                                      atol=1e-5),
                         batched, singles[s][chunk])  # fmt: skip
    metrics = jax.device_get(jax.jit(train.evaluate)(state, jax.random.PRNGKey(1)))
    assert "eval/planner_return" not in metrics  # no planner: the actor is evaluated once
    assert float(metrics["eval/policy_length"]) == T
    assert 0.0 <= float(metrics["eval/policy_return"]) <= T


STEPS, STOP_AT = 650, 550  # the first 250-step episodes end at 500 env steps (2 envs)
BASE = ["--preset", "fasttd3-smoke", "--task", "pendulum", "--steps", str(STEPS),
        "--seed-steps", "200", "--chunk-steps", "25", "--num-envs", "2",
        "--eval-every", str(STEPS), "--log-every", "50", "--checkpoint-every", "0",
        "--no-progress"]  # fmt: skip


@pytest.mark.slow  # 3 min: train, resume, eval, export compiles (test_cli covers the shared shell)
@pytest.mark.timeout(600)
def test_cli_trains_resumes_bit_identical_evaluates_and_exports(tmp_path, capsys):
    from test_cli import _load_final, train_interrupted

    from sirl_jax.run import cli

    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.main(["train", *BASE, "--run-dir", str(a)]) == 0
    assert train_interrupted([*BASE, "--run-dir", str(b)], STOP_AT) == (0, [STOP_AT])
    assert cli.main(["train", "--resume", str(b), "--no-progress"]) == 0
    step_a, leaves_a = _load_final(a)
    step_b, leaves_b = _load_final(b)
    assert step_a == step_b == STEPS and len(leaves_a) == len(leaves_b)
    for x, y in zip(leaves_a, leaves_b, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))

    capsys.readouterr()
    assert cli.main(["eval", str(a), "--episodes", "2"]) == 0
    assert "policy" in capsys.readouterr().out
    out = tmp_path / "export"
    assert cli.main(["export", str(a), "--out", str(out)]) == 0
    assert (out / "policy.onnx").exists() and not (out / "planner.jax").exists()
    import onnxruntime as ort

    from sirl_jax.agent.fasttd3 import policy_from_params
    from sirl_jax.run import runlog
    from sirl_jax.run.export import nested_params

    config = runlog.load_config(a)
    params = nested_params(dict(np.load(out / "params.npz")))
    obs = np.random.default_rng(0).normal(size=(4, 3)).astype(np.float32)
    want = np.asarray(policy_from_params(config.agent, 1, params)(jnp.asarray(obs)))
    got = ort.InferenceSession(str(out / "policy.onnx")).run(None, {"obs": obs})[0]
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
