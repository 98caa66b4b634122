"""The MJX pendulum swing-up and the MuJoCo Playground adapter."""

import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.envs import TASKS, VecEnv
from sirl_jax.envs.classic import PendulumSwingup, energy_swingup_action

E = 8


@pytest.fixture(scope="module")
def pendulum():
    return PendulumSwingup()


@pytest.fixture(scope="module")
def rollout(pendulum):
    vec = VecEnv(pendulum, E)

    @jax.jit
    def run(key, gain):
        """gain 0: zero torque; gain 1: the energy-pumping swing-up controller."""
        state = vec.reset(key)

        def body(s, _):
            s = vec.step(s, gain * energy_swingup_action(s.obs))
            return s, (s.reward, s.final_obs, s.metrics)

        return jax.lax.scan(body, state, None, length=pendulum.episode_length)

    return run


def test_registered():
    spec = TASKS["pendulum"]
    assert spec.id == "pendulum-swingup-v0"
    assert spec.episode_length == 250 and spec.success_bar == 150.0
    env = spec.factory()
    assert (env.observation_size, env.action_size, env.episode_length) == (3, 1, 250)


@pytest.mark.timeout(240)
def test_rollout_obs_and_reward_terms(rollout):
    _, (reward, obs, metrics) = rollout(jax.random.PRNGKey(0), 0.0)
    reward, obs = np.asarray(reward), np.asarray(obs)
    assert obs.shape == (250, E, 3) and np.all(np.isfinite(obs))
    np.testing.assert_allclose(obs[..., 0] ** 2 + obs[..., 1] ** 2, 1.0, atol=1e-5)
    assert np.all((reward >= 0) & (reward <= 1))
    product = metrics["upright"] * metrics["small_control"] * metrics["small_velocity"]
    np.testing.assert_allclose(reward, product, rtol=1e-6)
    # Zero torque: small_control is exactly (4 + 1) / 5 = 1.
    np.testing.assert_allclose(metrics["small_control"], 1.0)
    # upright = (1 + cos theta) / 2 from the observed cos theta.
    np.testing.assert_allclose(metrics["upright"], (1 + obs[..., 0]) / 2, atol=1e-5)


@pytest.mark.timeout(240)
def test_swingup_controller_reaches_success_bar_and_idle_does_not(rollout, pendulum):
    key = jax.random.PRNGKey(1)
    state_ctrl, (r_ctrl, _, _) = rollout(key, 1.0)
    state_idle, (r_idle, _, _) = rollout(key, 0.0)
    ret_ctrl, ret_idle = np.asarray(r_ctrl).sum(0), np.asarray(r_idle).sum(0)
    # The whole episode is one scan of T steps, so VecEnv's recorded return matches the sum.
    np.testing.assert_allclose(state_ctrl.last_return, ret_ctrl, rtol=1e-5)
    # The hand controller is not optimal: it averages well above the bar from random starts.
    assert np.mean(ret_ctrl) >= pendulum.success_bar + 25, ret_ctrl
    assert np.min(ret_ctrl) >= 0.8 * pendulum.success_bar, ret_ctrl
    assert np.mean(ret_idle) < pendulum.success_bar / 2, ret_idle


@pytest.mark.timeout(240)
def test_torque_limit_cannot_hold_horizontal(pendulum):
    # At theta = pi/2 gravity torque is m g l = 4.9 N m > the 2 N m motor: full torque against
    # gravity must still lose height.
    state = pendulum.reset(jax.random.PRNGKey(0))
    data = state.physics.replace(qpos=jnp.array([jnp.pi / 2]), qvel=jnp.zeros(1))
    state = state.replace(physics=data)
    step = jax.jit(pendulum.step)
    for _ in range(10):
        state = step(state, jnp.array([-1.0]))
    assert float(state.physics.qpos[0]) > jnp.pi / 2 + 0.05


def test_playground_missing_gives_a_clear_error(monkeypatch):
    from sirl_jax.envs import playground_adapter

    monkeypatch.setitem(sys.modules, "mujoco_playground", None)
    with pytest.raises(ImportError, match=r"sirl_jax\[playground\]"):
        playground_adapter.PlaygroundEnv("dmc:CartpoleSwingup")


def test_playground_rejects_unknown_names():
    pytest.importorskip("mujoco_playground")
    from sirl_jax.envs.playground_adapter import PlaygroundEnv

    with pytest.raises(ValueError, match="CartpoleSwingupp"):
        PlaygroundEnv("dmc:CartpoleSwingupp")
    with pytest.raises(ValueError, match="not a Playground task"):
        PlaygroundEnv("CartpoleSwingup")


@pytest.mark.timeout(300)
def test_playground_cartpole_steps():
    pytest.importorskip("mujoco_playground")
    from sirl_jax.envs.playground_adapter import register_playground_task

    spec = register_playground_task("dmc:CartpoleSwingup")
    assert spec.episode_length == 1000 and TASKS["dmc:CartpoleSwingup"] is spec
    env = spec.factory()
    assert (env.observation_size, env.action_size) == (5, 1)
    vec = VecEnv(env, 2)
    state = jax.jit(vec.reset)(jax.random.PRNGKey(0))
    step = jax.jit(vec.step)
    rewards = []
    for _ in range(3):
        state = step(state, jnp.full((2, 1), 0.5))
        rewards.append(np.asarray(state.reward))
    assert state.obs.shape == (2, 5) and np.all(np.isfinite(state.obs))
    np.testing.assert_array_equal(state.step_count, [3, 3])
    np.testing.assert_allclose(state.episode_return, np.sum(rewards, axis=0), rtol=1e-5)
    assert set(state.metrics) == set(env.metric_names())
