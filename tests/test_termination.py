"""The episodic termination head: BCE by hand, params only when episodic, planner masking, update.

Reference semantics (TD-MPC2 `main`): L_d = BCE_with_logits(termination(z_1..z_H), d_0..d_{H-1})
with mean reduction; in planning, a sample whose predicted P(terminal | z_{t+1}) > 0.5 keeps
r_t and loses every later reward and the terminal Q.
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig, make_agent
from sirl_jax.agent import losses as L
from sirl_jax.agent.networks import count_params, init_params
from sirl_jax.agent.planner import PlannerModel, estimate_value, make_planner
from sirl_jax.agent.world_model import make_world_model
from sirl_jax.types import Batch

R_MAX = jnp.array(100.0)  # the buffer R_max the updates receive (G = R_max)
O, A, T, H, B = 10, 4, 100, 3, 8
EPI = AgentConfig.tiny(episodic=True)


@pytest.mark.timeout(60)
def test_bce_with_logits_by_hand():
    x = [-2.0, 0.0, 3.0, 50.0, -50.0, 0.7]
    d = [1.0, 0.0, 1.0, 0.0, 1.0, 0.3]
    sig = [1.0 / (1.0 + math.exp(-v)) for v in x]
    # -[d log s + (1 - d) log(1 - s)], written with log1p to stay exact at |x| = 50.
    want = [
        di * math.log1p(math.exp(-xi)) + (1 - di) * math.log1p(math.exp(xi))
        for xi, di in zip(x, d, strict=True)
    ]
    np.testing.assert_allclose(want[:3], [-math.log(sig[0]), math.log(2), -math.log(sig[2])])
    got = L.bce_with_logits(jnp.array(x), jnp.array(d))
    np.testing.assert_allclose(got, want, rtol=1e-6)
    assert bool(jnp.all(jnp.isfinite(got)))


@pytest.mark.timeout(120)
def test_head_exists_only_when_episodic():
    plain = AgentConfig.tiny()
    shapes = {
        c.episodic: jax.eval_shape(lambda k, c=c: init_params(c, O, A, k), jax.random.PRNGKey(0))
        for c in (plain, EPI)
    }
    assert "termination" not in shapes[False] and "termination" in shapes[True]
    assert make_world_model(plain, A).termination_logit is None
    # z -> 32 -> 32 -> 1: two (Dense + LayerNorm) hidden layers and a Dense output.
    m, z = 32, 32
    head = (z * m + m + 2 * m) + (m * m + m + 2 * m) + (m + 1)
    assert count_params(shapes[True]["termination"]) == head
    assert count_params(shapes[True]) - count_params(shapes[False]) == head
    # Same key: every shared module gets the same values; the head's last layer is not zeroed.
    p0, p1 = jax.jit(lambda k: (init_params(plain, O, A, k), init_params(EPI, O, A, k)))(
        jax.random.PRNGKey(3)
    )
    for name in p0:
        jax.tree.map(np.testing.assert_array_equal, p0[name], p1[name])
    last = np.asarray(p1["termination"]["Dense_0"]["kernel"])
    assert last.shape == (m, 1) and 0.01 < last.std() < 0.03


def _lookup_model(termination):
    """z = [counter, l_0..l_3]: next adds 1 to the counter, r = 2^counter, Q = 100, and the
    termination logit of a latent is l_counter (a per-sample table)."""

    def logit(p, z):
        return jnp.take_along_axis(z[:, 1:], z[:, :1].astype(jnp.int32), axis=1)[:, 0]

    return PlannerModel(
        encode=lambda p, obs: obs,
        next=lambda p, z, a: z.at[:, 0].add(1.0),
        reward=lambda p, z, a: 2.0 ** z[:, 0],
        pi_sample=lambda p, z, k: jnp.zeros(z.shape[:-1] + (1,)),
        q_avg=lambda p, z, a, k: jnp.full(z.shape[:-1], 100.0),
        termination=logit if termination else None,
    )


@pytest.mark.timeout(60)
def test_estimate_value_masks_after_predicted_termination():
    g = 0.9
    table = np.array(
        [
            [1, -1, -1, -1],  # z_0 "terminal": never checked (only predicted latents are)
            [-1, 1, -1, -1],  # z_1 terminal: r_0 only; the later -1 does not unmask
            [-1, -1, 1, -1],  # z_2 terminal: r_0 + g r_1
            [-1, -1, -1, 1],  # z_3 terminal: all rewards, no terminal Q
            [-1, -1, -1, -1],  # never: all rewards + g^3 Q
            [-1, 0, -1, -1],  # logit 0: P = 0.5 is not > 0.5, so not terminal
        ],
        np.float32,
    )
    z = jnp.concatenate([jnp.zeros((6, 1)), jnp.asarray(table)], axis=1)
    actions = jnp.zeros((H, 6, 1))
    r = [1.0, 2.0, 4.0]
    full = r[0] + g * r[1] + g**2 * r[2]
    want = [full + g**3 * 100, r[0], r[0] + g * r[1], full, full + g**3 * 100, full + g**3 * 100]
    run = jax.jit(
        lambda z: estimate_value(_lookup_model(True), {}, z, actions, jax.random.PRNGKey(0), g)
    )
    np.testing.assert_allclose(run(z), want, rtol=1e-6)
    # Without a head (not episodic) nothing is masked.
    plain = estimate_value(_lookup_model(False), {}, z, actions, jax.random.PRNGKey(0), g)
    np.testing.assert_allclose(plain, [want[0]] * 6, rtol=1e-6)
    # A head that never fires gives exactly the unmasked values (masking multiplies by 1.0).
    never = z.at[:, 1:].set(-1.0)
    np.testing.assert_array_equal(run(never), plain)


@pytest.mark.timeout(120)
def test_planner_avoids_predicted_termination():
    """Latent = last action; r = a_0 pulls a_0 to 1, but a_0 > 0.5 is predicted terminal and
    loses Q = 10 (V ~ 1 vs ~ 8.6 when staying at 0.5); without the head the mean goes to 1."""
    cfg = AgentConfig.tiny(num_samples=128, num_elites=16, num_pi_trajs=4, iterations=6)
    traces = []

    def encode(p, obs):
        traces.append(1)
        return obs

    def model(termination):
        return PlannerModel(
            encode=encode,
            next=lambda p, z, a: a,
            reward=lambda p, z, a: a[..., 0],
            pi_sample=lambda p, z, k: jax.random.uniform(k, z.shape, minval=-1, maxval=1),
            q_avg=lambda p, z, a, k: jnp.full(z.shape[:-1], 10.0),
            termination=(lambda p, z: 20.0 * (z[..., 0] - 0.5)) if termination else None,
        )

    obs = jnp.zeros((2, 2))
    step0 = {}
    for episodic in (True, False):
        planner = make_planner(cfg, 2, 0.9, cfg.iterations, model(episodic))
        plan, state = jax.jit(planner.plan), planner.init(2)
        first = jnp.array([True, True])
        for i in range(4):
            _, state = plan({}, state, obs, first, jax.random.PRNGKey(i))
            first = jnp.array([False, False])
        step0[episodic] = np.asarray(state.prev_mean[:, :, 0])
    assert len(traces) == 2  # one trace per planner, none per call
    assert np.all(step0[True] < 0.5) and np.all(step0[True] > 0.2), step0[True]
    assert np.all(step0[False] > 0.8), step0[False]


def _batch(key):
    k1, k2, k3, k4 = jax.random.split(key, 4)
    return Batch(
        obs=jax.random.normal(k1, (H + 1, B, O)),
        action=jnp.tanh(jax.random.normal(k2, (H, B, A))),
        reward=jax.random.uniform(k3, (H, B), minval=-1.0, maxval=3.0),
        terminated=(jax.random.uniform(k4, (H, B)) < 0.3).astype(jnp.float32),
        episode_return=jnp.linspace(-50.0, 150.0, B),
    )


@pytest.fixture(scope="module")
def episodic_update():
    agent = make_agent(EPI, O, A, T)
    state = jax.jit(agent.init)(jax.random.PRNGKey(0))
    return agent, state, jax.jit(agent.update), _batch(jax.random.PRNGKey(1))


@pytest.mark.timeout(240)
def test_episodic_update_trains_the_head(episodic_update):
    agent, state, update, batch = episodic_update
    assert "termination" in state.params
    new, m = update(state, batch, R_MAX, jax.random.PRNGKey(2))
    assert all(v.shape == () and bool(jnp.isfinite(v)) for v in m.values())
    # wm_loss = 20 L_c + 0.1 L_r + 0.1 L_q + 1 * L_d.
    rest = 20 * m["consistency_loss"] + 0.1 * m["reward_loss"] + 0.1 * m["value_loss"]
    assert float(m["wm_loss"] - rest) == pytest.approx(float(m["termination_loss"]), rel=1e-4)
    # Small-init head: logits ~ 0, so each BCE term is close to ln 2.
    assert float(m["termination_loss"]) == pytest.approx(math.log(2), abs=0.05)
    # Adam's first step moves every leaf that got a gradient (global clip included).
    moved = jax.tree.map(
        lambda a, b: float(jnp.max(jnp.abs(a - b))),
        new.params["termination"],
        state.params["termination"],
    )
    assert all(v > 1e-5 for v in jax.tree.leaves(moved)), moved
    s = new
    for i in range(30):
        s, m2 = update(s, batch, R_MAX, jax.random.PRNGKey(10 + i))
    assert float(m2["termination_loss"]) < float(m["termination_loss"]) - 0.05


@pytest.mark.timeout(240)
def test_termination_loss_on_rollout_latents_with_gradients(episodic_update):
    agent, state, _, batch = episodic_update
    wm = make_world_model(EPI, A)
    wm_params = {k: v for k, v in state.params.items() if k != "policy"}

    def l_d(p):
        _, (zs, m) = L.world_model_loss(
            wm,
            EPI,
            agent.discount,
            p,
            state.params["policy"],
            state.target_qs,
            batch,
            jax.random.PRNGKey(4),
        )
        return m["termination_loss"], zs

    (got, zs), grads = jax.jit(jax.value_and_grad(l_d, has_aux=True))(wm_params)
    logits = wm.termination_logit(state.params, zs[1:])  # z_1..z_H pair with d_0..d_{H-1}
    x, d = np.asarray(logits, np.float64), np.asarray(batch.terminated, np.float64)
    want = np.mean(np.maximum(x, 0) - x * d + np.log1p(np.exp(-np.abs(x))))
    assert float(got) == pytest.approx(want, rel=1e-5)
    shifted = wm.termination_logit(state.params, zs[:-1])
    assert float(jnp.mean(L.bce_with_logits(shifted, batch.terminated))) != pytest.approx(want)
    norm = {
        k: float(jnp.sqrt(sum(jnp.sum(g**2) for g in jax.tree.leaves(v)))) for k, v in grads.items()
    }
    assert norm["termination"] > 0 and norm["dynamics"] > 0 and norm["encoder"] > 0, norm
    assert norm["reward"] == 0 and norm["qs"] == 0, norm


def _episodic_train(chunk_steps=5, seed_steps=20):
    from sirl_jax.config import Config, TrainConfig
    from sirl_jax.envs.classic import PendulumSwingup
    from sirl_jax.train import make_train

    tc = TrainConfig(
        task="pendulum",
        steps=1_000,
        num_envs=2,
        chunk_steps=chunk_steps,
        seed_steps=seed_steps,
        utd=0.5,
        buffer_size=1_000,
        eval_episodes=1,
    )
    cfg = Config(agent=dataclasses.replace(EPI, batch_size=8), train=tc)
    return make_train(cfg, PendulumSwingup(episode_length=50))


@pytest.mark.timeout(240)
def test_train_step_traces_with_episodic_on_pendulum():
    train = _episodic_train()
    state = jax.eval_shape(train.init, jax.random.PRNGKey(0))
    assert "termination" in state.agent.params
    new, metrics = jax.eval_shape(train.step, state)
    assert "train/termination_loss" in metrics
    assert jax.tree.structure(new) == jax.tree.structure(state)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_train_step_runs_with_episodic_on_pendulum():
    """Real chunks: seed phase, pretraining, then planning with the head (pendulum never
    terminates, so the head learns d = 0 and its loss falls)."""
    train = _episodic_train(chunk_steps=25, seed_steps=100)
    step = jax.jit(train.step)
    state = jax.jit(train.init)(jax.random.PRNGKey(0))
    history = []
    for _ in range(4):
        state, m = step(state)
        history.append(jax.device_get(m))
    assert [float(m["planning"]) for m in history] == [0.0, 1.0, 1.0, 1.0]
    for m in history:
        assert int(m["env/blowups"]) == 0 and int(m["nonfinite_loss"]) == 0
    losses = [float(m["train/termination_loss"]) for m in history[1:]]
    assert all(np.isfinite(losses)) and losses[-1] < losses[0], losses
