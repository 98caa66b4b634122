"""The fused train step: seed phase, pretraining, UTD bookkeeping, one compile, seeds vmapped.

Setup (hand-computed expectations): E = 2 pendulums with 50-step episodes, K = 25 steps per
chunk (50 transitions), seed_steps = 100 transitions, utd = 0.75. Chunks 1-2 act randomly;
the last step of chunk 2 reaches 100 transitions with one finished 50-step episode per env, so
pretraining runs 100 * 0.75 = 75 updates there and planning starts in chunk 3. From then on each
vectorised step owes E * utd = 1.5 updates: 25 steps of chunk 3 run floor(37.5) = 37 updates
and carry 0.5.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs.classic import PendulumSwingup
from sirl_jax.presets import PRESETS, get_preset, register_preset
from sirl_jax.run.config_rules import fit_to_task
from sirl_jax.train import make_train, update_schedule

E, K, T, SEED_STEPS, UTD = 2, 25, 50, 100, 0.75


def _config(**train) -> Config:
    base = dict(
        task="pendulum",
        steps=1_000,
        num_envs=E,
        chunk_steps=K,
        seed_steps=SEED_STEPS,
        utd=UTD,
        buffer_size=1_000,
        eval_episodes=2,
    )
    base.update(train)
    return Config(agent=AgentConfig.tiny(batch_size=8), train=TrainConfig(**base))


@pytest.fixture(scope="module")
def train():
    return make_train(_config(), PendulumSwingup(episode_length=T))


@pytest.fixture(scope="module")
def compiled(train):
    traces = []

    def counted_step(state):
        traces.append(1)
        return train.step(state)

    return jax.jit(train.init), jax.jit(counted_step, donate_argnums=0), traces


def _tree_allclose(a, b, **tol):
    jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, **tol), a, b)


@pytest.mark.timeout(420)
def test_seed_phase_pretraining_and_planning(train, compiled):
    init, step, traces = compiled
    assert train.config.train.steps_per_call == K * E and train.seed_steps == SEED_STEPS
    assert train.pretrain_updates == 75
    state = init(jax.random.PRNGKey(0))
    params0 = jax.device_get(state.agent.params)
    history = []
    for _ in range(6):
        state, metrics = step(state)
        history.append((jax.device_get(state.planner.prev_mean), jax.device_get(metrics)))
        if len(history) == 1:
            # Seed phase: no update touched the networks, the planner never ran.
            _tree_allclose(jax.device_get(state.agent.params), params0, rtol=0, atol=0)
    assert len(traces) == 1, "the train step must compile once"

    planning = [float(m["planning"]) for _, m in history]
    updates = [int(m["updates"]) for _, m in history]
    assert planning == [0.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    # 75 pretraining updates at 100 transitions; then 1.5 per step (37, 38, 37, 38 per chunk).
    assert updates == [0, 75, 112, 150, 187, 225]
    assert int(history[1][1]["train/num_updates"]) == 75
    np.testing.assert_allclose(float(state.update_debt), 0.0)
    for prev_mean, _ in history[:2]:
        assert np.all(prev_mean == 0.0)
    assert np.any(history[2][0] != 0.0), "the planner's warm start must be set once it plans"

    for i, (_, m) in enumerate(history, start=1):
        assert int(m["env_steps"]) == i * K * E
        assert int(m["env/blowups"]) == 0 and int(m["nonfinite_loss"]) == 0
    # Each chunk of 25 steps ends an episode of 50 steps per env every other chunk.
    assert [int(m["episode/count"]) for _, m in history] == [0, 2, 0, 2, 0, 2]
    np.testing.assert_allclose(float(history[1][1]["episode/length"]), T)
    assert np.isnan(float(history[0][1]["episode/return"]))
    last = history[-1][1]
    assert int(last["buffer/episodes"]) == 6
    for name, value in last.items():
        if name.startswith("train/"):
            assert np.isfinite(value), name
    # G = R_max: the best of the 6 recorded episode returns, each at most T.
    assert 0.0 < float(last["r_max"]) <= T
    assert float(last["sirl/reference"]) == float(last["r_max"])
    assert 0.0 <= float(last["sirl/clamped_fraction"]) <= 1.0


@pytest.mark.slow  # 37 s cold; make test has the same check through the sweep (test_sweep.py)
@pytest.mark.timeout(420)
def test_vmapped_seeds_equal_single_runs(train, compiled):
    """S = 2 seeds in one vmapped program equal two single runs with the same keys.

    Compared tightly through the seed phase and the 75 pretraining updates (chunks 1-2). In
    chunk 3 the planner acts: MPPI's top-k turns float reassociation under vmap into slightly
    different actions that the pendulum then amplifies, so only the networks are compared.
    """
    init, step, _ = compiled
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    vstep = jax.jit(jax.vmap(train.step), donate_argnums=0)
    vstate = jax.jit(jax.vmap(train.init))(keys)
    vhist = []
    for _ in range(3):
        vstate, vmetrics = vstep(vstate)
        vhist.append(jax.device_get((vstate.agent.params, vstate.buffer.obs, vmetrics)))
    for s in range(2):
        state = init(keys[s])
        for chunk in range(3):
            state, metrics = step(state)
            single = jax.device_get((state.agent.params, state.buffer.obs, metrics))
            batched = jax.tree.map(lambda x, s=s: x[s], vhist[chunk])
            if chunk < 2:
                _tree_allclose(batched, single, rtol=1e-4, atol=1e-5)
            else:
                _tree_allclose(batched[0], single[0], rtol=2e-3, atol=2e-4)
                assert batched[2]["updates"] == single[2]["updates"]


@pytest.mark.timeout(300)
def test_evaluate(train, compiled):
    init, step, _ = compiled
    state = init(jax.random.PRNGKey(0))
    for _ in range(3):
        state, _ = step(state)
    metrics = jax.device_get(jax.jit(train.evaluate)(state, jax.random.PRNGKey(1)))
    for mode in ("planner", "policy"):
        assert float(metrics[f"eval/{mode}_length"]) == T
        ret = float(metrics[f"eval/{mode}_return"])
        assert 0.0 <= ret <= T
        # Success bar 150 is out of reach in 50 steps (reward <= 1 per step).
        assert float(metrics[f"eval/{mode}_success"]) == 0.0
    assert float(metrics["eval/r_max"]) == float(jax.device_get(state.buffer.r_max))


@pytest.mark.timeout(300)
def test_baseline_policies_spend_the_control_they_should():
    """The pendulum's small_control term is (4 + 1 - u^2) / 5: exactly 1 for the zero-action
    baseline, and (4 + 2/3) / 5 = 0.933 in expectation for uniform random actions."""
    from sirl_jax.evaluate import make_random_evaluate

    env, key = PendulumSwingup(episode_length=T), jax.random.PRNGKey(0)
    zero = jax.device_get(jax.jit(make_random_evaluate(env, 4, "zero"))(key))
    assert float(zero["eval/zero_term/small_control"]) == pytest.approx(1.0, abs=1e-6)
    assert float(zero["eval/zero_length"]) == T
    rand = jax.device_get(jax.jit(make_random_evaluate(env, 4))(key))
    assert 0.91 < float(rand["eval/random_term/small_control"]) < 0.955
    with pytest.raises(ValueError, match="action='gaussian' is invalid"):
        make_random_evaluate(env, 4, "gaussian")


def test_seed_steps_and_capacity():
    tc = TrainConfig(num_envs=4, steps=500, buffer_size=3_000_000)
    assert tc.resolved_seed_steps(1000) == 5000 * 4
    assert tc.resolved_seed_steps(100) == 1000 * 4
    assert dataclasses.replace(tc, seed_steps=101).resolved_seed_steps(1000) == 104
    assert tc.capacity == 500 and tc.steps_per_call == 400
    assert dataclasses.replace(tc, utd=0.5).pretrain_updates(100) == 2000
    assert dataclasses.replace(tc, pretrain=False).pretrain_updates(100) == 0


def test_config_validation_names_the_field():
    with pytest.raises(ValueError, match=r"train\.utd=0"):
        TrainConfig(utd=0)
    with pytest.raises(ValueError, match=r"train\.num_envs=0"):
        TrainConfig(num_envs=0)
    cfg = Config(agent=AgentConfig.tiny(sirl=SirlConfig(g_source="target")))
    with pytest.raises(ValueError, match="success bar"):
        make_agent(cfg.agent, obs_size=3, action_size=1, episode_length=100, success_bar=None)
    with pytest.raises(ValueError, match="episode_length"):
        cfg.validate_for_task(episode_length=3)


def test_presets():
    assert {"default", "smoke", "cpu"} <= set(PRESETS)
    assert get_preset("default") == Config()
    assert get_preset("smoke").agent.model_size == "tiny"
    with pytest.raises(ValueError, match="already registered"):
        register_preset("smoke", Config)
    with pytest.raises(KeyError, match="valid presets"):
        get_preset("nope")


@pytest.mark.timeout(60)
def test_target_return_ref_needs_a_success_bar():
    cfg = _config()
    cfg = dataclasses.replace(
        cfg, agent=dataclasses.replace(cfg.agent, sirl=SirlConfig(g_source="target"))
    )
    tr = make_train(cfg, PendulumSwingup(episode_length=T))
    assert float(tr.agent.sirl_reference(123.0)) == PendulumSwingup(episode_length=T).success_bar
    plain = make_train(_config(), PendulumSwingup(episode_length=T))
    assert float(plain.agent.sirl_reference(123.0)) == 123.0


def _schedule(planning, env_steps, debt, can_sample=True, **kw):
    args = dict(updates_per_step=3.0, seed_steps=100, pretrain_updates=75)
    args.update(kw)
    num, debt, planning = update_schedule(
        jnp.asarray(planning), jnp.asarray(env_steps), jnp.float32(debt), jnp.asarray(can_sample),
        **args,
    )
    return int(num), float(debt), bool(planning)


def test_update_schedule_by_hand():
    # Seed phase: nothing owed, nothing carried.
    assert _schedule(False, 96, 0.0) == (0, 0.0, False)
    # The step reaching seed_steps starts planning with the pretraining burst.
    assert _schedule(False, 100, 0.0) == (75, 0.0, True)
    # ...but not before the buffer can sample: planning waits, nothing is owed.
    assert _schedule(False, 100, 0.0, can_sample=False) == (0, 0.0, False)
    # Planning: 3 per step (4 envs x UTD 0.75); 1.2 per step carries 0.2 each time.
    assert _schedule(True, 104, 0.0) == (3, 0.0, True)
    num, debt, _ = _schedule(True, 104, 0.0, updates_per_step=1.2)
    assert num == 1 and debt == pytest.approx(0.2)
    num, debt, _ = _schedule(True, 108, 0.8, updates_per_step=1.2)  # 0.8 + 1.2 = 2: two, no debt
    assert num == 2 and debt == pytest.approx(0.0, abs=1e-6)
    num, debt, _ = _schedule(True, 108, 0.5, updates_per_step=0.25)  # 0.75: none yet
    assert num == 0 and debt == pytest.approx(0.75)


def test_cpu_presets_fit_a_task_with_long_episodes():
    smoke = get_preset("smoke")
    same, derived = fit_to_task(smoke, 250)  # the pendulum: the preset as it is
    assert same == smoke and derived == {}
    fitted, derived = fit_to_task(smoke, 1000)  # dmc:CartpoleSwingup, 4 envs
    need = 2 * 4 * 1001
    assert derived == {"train.buffer_size": (4_000, need), "train.steps": (4_000, need),
                       "train.seed_steps": (1_000, 4_000), "train.eval_every": (2_000, 4_000)}
    assert fitted.train.capacity == need and fitted.agent == smoke.agent
    fitted.validate_for_task(1000)  # one episode per env fits
    with pytest.raises(ValueError, match="train.buffer_size"):
        smoke.validate_for_task(1000)
    cpu, derived = fit_to_task(get_preset("cpu"), 1000)
    assert cpu.train.seed_steps is None and derived["train.eval_every"] == (2_000, 8_000)
