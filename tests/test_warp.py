"""The physics backend option: impl="warp" (MJX-Warp on Warp's CPU device) against impl="jax".

Tolerances: the same model, start and actions give qpos within 1e-5 on the pendulum and the
cartpole, and within H1_QPOS_ATOL on h1hand-walk after 50 control steps (500 substeps of a
1-iteration Newton solver, float32; measured max error 0.0145 over 4 envs, see
docs/training.md).
"""

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import VecEnv, h1, load, make, physics
from sirl_jax.envs.classic import energy_swingup_action
from sirl_jax.envs.physics import Physics

H1_QPOS_ATOL = 0.05
STEPS = 50

needs_warp = pytest.mark.skipif(
    physics.warp_unavailable() is not None, reason=str(physics.warp_unavailable())
)


def _no_warp(monkeypatch):
    def fail():
        raise ImportError("No module named 'warp'")

    monkeypatch.setattr(physics, "_import_warp", fail)


def _one_line(error) -> str:
    text = str(error.value)
    assert "\n" not in text
    return text


def test_warp_without_warp_lang_is_one_line_error(monkeypatch):
    _no_warp(monkeypatch)
    assert "warp-lang is not installed" in physics.warp_unavailable()
    with pytest.raises(ImportError) as error:
        physics.check_impl("warp")
    assert "warp-lang is not installed" in _one_line(error)
    with pytest.raises(ImportError) as error:
        load("pendulum", physics=Physics("warp"))
    assert "pip install 'sirl_jax[warp]'" in _one_line(error)
    physics.check_impl("jax")  # the jax path needs no warp-lang


def test_warp_without_warp_lang_is_a_usage_error_in_train(monkeypatch):
    from sirl_jax.run import runner
    from sirl_jax.run.errors import UsageError

    _no_warp(monkeypatch)
    config = Config(train=TrainConfig(task="pendulum", impl="warp"))
    with pytest.raises(UsageError) as error:
        runner.build(config)
    assert _one_line(error).startswith("--train.impl warp: impl='warp' cannot be used: warp-lang")


def test_warp_where_it_cannot_run_says_which(monkeypatch):
    monkeypatch.setattr(physics, "_import_warp", lambda: None)
    monkeypatch.setattr(physics.jax, "default_backend", lambda: "tpu")
    with pytest.raises(RuntimeError) as error:
        physics.check_impl("warp")
    assert "Warp runs on a CUDA GPU or the CPU" in _one_line(error) and "'tpu'" in str(error.value)


def test_bad_impl_and_physics_fields_are_one_line_errors():
    for kwargs, name in [({"impl": "cuda"}, "impl"), ({"num_worlds": 0}, "num_worlds"),
                         ({"margin": 0.0}, "margin")]:  # fmt: skip
        with pytest.raises(ValueError) as error:
            Physics(**kwargs)
        assert _one_line(error).startswith(f"{name}=")
    with pytest.raises(ValueError) as error:
        TrainConfig(impl="cuda")
    assert _one_line(error) == "train.impl='cuda' is invalid; allowed: 'jax' or 'warp'"
    assert TrainConfig().impl == "jax"


def test_contact_profile_bounds_a_fall_and_sizes_the_buffers():
    model = make("h1hand-walk-v0").mj_model
    contacts, rows = physics.contact_profile(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    most = [0, 0]
    for _ in range(1500):  # zero torque: the robot falls and lies on the floor
        mujoco.mj_step(model, data)
        most = [max(most[0], data.ncon), max(most[1], data.nefc)]
    assert data.qpos[2] < 0.3
    assert contacts >= most[0] and rows >= most[1]
    buffers = physics.warp_buffers(model, Physics("warp", num_worlds=8, margin=1.5))
    assert buffers.nconmax == math.ceil(1.5 * contacts) and buffers.njmax == math.ceil(1.5 * rows)
    assert buffers.naconmax == 8 * buffers.nconmax


def test_contact_profile_ignores_the_jax_pair_pruning():
    model = make("h1hand-maze-v0").mj_model
    pruned = int(mjx.make_data(model, impl="jax")._impl.contact.dist.shape[0])
    assert physics.contact_profile(model)[0] > pruned


def _rollout(name: str, impl: str, num_envs: int, policy, **kwargs):
    _, env = load(name, physics=Physics(impl, num_worlds=num_envs), **kwargs)
    vec = VecEnv(env, num_envs)

    @jax.jit
    def run(key):
        def body(s, t):
            s = vec.step(s, policy(s.obs, t, env))
            return s, (s.first, s.metrics)

        return jax.lax.scan(body, vec.reset(key), jnp.arange(STEPS, dtype=jnp.float32))

    state, (first, metrics) = run(jax.random.PRNGKey(0))
    return env, state, np.asarray(first), jax.device_get(metrics)


def _swing(obs, t, env):
    del t, env
    return energy_swingup_action(obs)


def _push(obs, t, env):
    return jnp.full((obs.shape[0], env.action_size), 0.3)


@needs_warp
@pytest.mark.timeout(400)
@pytest.mark.parametrize(
    "name, policy, kwargs",
    [pytest.param("pendulum", _swing, {"episode_length": 20}, marks=pytest.mark.slow),  # 34 s
     pytest.param("dmc:CartpoleSwingup", _push, {}, marks=pytest.mark.slow)],  # 22 s idle
)
def test_warp_vec_env_matches_jax_through_auto_resets(name, policy, kwargs):
    qpos = {}
    for impl in ("jax", "warp"):
        env, state, first, metrics = _rollout(name, impl, 2, policy, **kwargs)
        qpos[impl] = np.asarray(env.mjx_data(state.physics).qpos)
        assert np.all(np.isfinite(np.asarray(state.obs)))
    assert first.sum() == (4 if name == "pendulum" else 0)  # resets at steps 20 and 40
    assert metrics[physics.OVERFLOW_METRIC].sum() == 0
    assert set(metrics) - {physics.OVERFLOW_METRIC} == set(env.metric_names()) - {
        physics.OVERFLOW_METRIC
    }
    np.testing.assert_allclose(qpos["warp"], qpos["jax"], atol=1e-5)


def _stand(obs, t, env):
    a = jnp.asarray(env.robot.keyframe_action) + 0.05 * jnp.sin(0.3 * t)
    return jnp.clip(jnp.broadcast_to(a, (obs.shape[0], env.action_size)), -1.0, 1.0)


@needs_warp
@pytest.mark.slow  # 128 s on a fresh clone; the pendulum and contact tests stay fast
@pytest.mark.timeout(600)
def test_warp_h1hand_walk_matches_jax_after_50_control_steps():
    out = {}
    for impl in ("jax", "warp"):
        _, state, first, metrics = _rollout("h1hand-walk-v0", impl, 2, _stand)
        out[impl] = (np.asarray(state.physics.qpos), metrics, first)
    (q_jax, _, first), (q_warp, m_warp, _) = out["jax"], out["warp"]
    assert not first.any()  # standing: no env fell or reset
    assert m_warp[physics.OVERFLOW_METRIC].sum() == 0
    assert np.abs(q_warp - q_jax).max() <= H1_QPOS_ATOL


@needs_warp
@pytest.mark.timeout(400)
def test_warp_contact_arrays_are_per_world_and_match_jax():
    """World 0 stands 5 mm into the floor, world 1 floats 0.5 m above it: the shared pool's
    contacts must land in world 0 only, with the geom pairs MJX-JAX finds."""
    model = make("h1-walk-v0").mj_model
    qpos = np.repeat(model.key_qpos[:1], 2, axis=0)
    qpos[:, 2] += np.array([-0.005, 0.5])
    pairs = {}
    for impl in ("jax", "warp"):
        sim = physics.Simulator(model, Physics(impl, num_worlds=2))
        d0 = h1.keyframe_data(model, sim.mx, sim=sim)

        def touching(q, sim=sim, d0=d0):
            d = mjx.forward(sim.mx, sim.attach_pool(d0.replace(qpos=q)))
            dist, geom = physics.contact_arrays(d)
            return dist < 0, geom

        hit, geom = jax.device_get(jax.jit(jax.vmap(touching))(jnp.asarray(qpos, jnp.float32)))
        pairs[impl] = [{tuple(sorted(g)) for g, h in zip(geom[w], hit[w], strict=True) if h}
                       for w in (0, 1)]  # fmt: skip
    assert pairs["jax"][0] and not pairs["jax"][1]
    assert pairs["warp"] == pairs["jax"]


@needs_warp
@pytest.mark.timeout(400)
def test_warp_buffer_too_small_is_counted_and_one_line_error():
    tiny = Physics("warp", num_worlds=2, margin=0.05)  # 2 contacts per world; feet make 8
    _, env = load("h1-walk-v0", physics=tiny, episode_length=3)
    vec = VecEnv(env, 2)

    @jax.jit
    def run(key):
        def body(s, _):
            s = vec.step(s, jnp.zeros((2, env.action_size)))
            return s, s.metrics[physics.OVERFLOW_METRIC]

        return jax.lax.scan(body, vec.reset(key), None, length=5)

    overflow = np.asarray(run(jax.random.PRNGKey(0))[1])
    assert overflow.shape == (5, 2) and overflow.sum() > 0
    with pytest.raises(RuntimeError) as error:
        physics.raise_on_overflow(overflow, "of h1-walk-v0", env.sim.buffers)
    text = _one_line(error)
    assert text.startswith("Warp contact/constraint buffer too small (naconmax 4 = 2 per world")
    physics.raise_on_overflow(np.zeros(3), "none")
