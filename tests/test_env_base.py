"""VecEnv auto-reset semantics on a tiny pure-JAX counter env (no physics, fast to compile).

The toy env: position p starts at 0, each step adds 1 and pays reward p_{t+1}; an action > 0.5
terminates. Obs = [p, 7]. So after t steps without termination the return is t (t + 1) / 2.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.envs.base import Env, EnvState, VecEnv, init_state

T = 5


class CounterEnv(Env):
    @property
    def observation_size(self) -> int:
        return 2

    @property
    def action_size(self) -> int:
        return 1

    @property
    def episode_length(self) -> int:
        return T

    def metric_names(self):
        return ("double_reward",)

    def reset(self, key):
        p = jnp.zeros((), jnp.float32)
        return init_state(p, self._obs(p), key, metrics={"double_reward": jnp.zeros(())})

    def step(self, state: EnvState, action):
        p = state.physics + 1.0
        return state.replace(
            physics=p,
            obs=self._obs(p),
            reward=p,
            terminated=action[0] > 0.5,
            metrics={"double_reward": 2.0 * p},
        )

    @staticmethod
    def _obs(p):
        return jnp.stack([p, jnp.float32(7.0)])


@pytest.fixture(scope="module")
def vec():
    v = VecEnv(CounterEnv(), 2)
    return v, jax.jit(v.reset), jax.jit(v.step)


def _run(vec, actions):
    v, reset, step = vec
    state = reset(jax.random.PRNGKey(0))
    states = []
    for a in actions:
        state = step(state, jnp.asarray(a, jnp.float32).reshape(2, 1))
        states.append(jax.device_get(state))
    return states


@pytest.mark.timeout(120)
def test_truncation_at_episode_length(vec):
    states = _run(vec, [[0.0, 0.0]] * (T + 2))
    for t, s in enumerate(states[: T - 1], start=1):
        np.testing.assert_array_equal(s.truncated, [False, False])
        np.testing.assert_array_equal(s.first, [False, False])
        np.testing.assert_array_equal(s.final_obs, s.obs)
        np.testing.assert_array_equal(s.step_count, [t, t])
        np.testing.assert_allclose(s.episode_return, [t * (t + 1) / 2] * 2)
        assert np.all(np.isnan(s.last_return))
    end = states[T - 1]
    np.testing.assert_array_equal(end.truncated, [True, True])
    np.testing.assert_array_equal(end.terminated, [False, False])
    np.testing.assert_array_equal(end.first, [True, True])
    np.testing.assert_array_equal(end.final_obs, [[T, 7.0]] * 2)
    np.testing.assert_array_equal(end.obs, [[0.0, 7.0]] * 2)
    np.testing.assert_array_equal(end.step_count, [0, 0])
    np.testing.assert_allclose(end.episode_return, [0.0, 0.0])
    np.testing.assert_allclose(end.last_return, [T * (T + 1) / 2] * 2)
    np.testing.assert_array_equal(end.last_length, [T, T])
    np.testing.assert_allclose(end.reward, [T, T])
    np.testing.assert_allclose(end.metrics["double_reward"], [2 * T] * 2)
    after = states[T]
    np.testing.assert_array_equal(after.first, [False, False])
    np.testing.assert_array_equal(after.obs, [[1.0, 7.0]] * 2)
    np.testing.assert_allclose(after.last_return, [T * (T + 1) / 2] * 2)


@pytest.mark.timeout(120)
def test_termination_is_per_env_and_not_truncation(vec):
    # env 0 terminates at its 3rd step; env 1 runs on.
    states = _run(vec, [[0, 0], [0, 0], [1, 0], [0, 0]])
    s3 = states[2]
    np.testing.assert_array_equal(s3.terminated, [True, False])
    np.testing.assert_array_equal(s3.truncated, [False, False])
    np.testing.assert_array_equal(s3.first, [True, False])
    np.testing.assert_array_equal(s3.final_obs[0], [3.0, 7.0])
    np.testing.assert_array_equal(s3.obs[0], [0.0, 7.0])
    np.testing.assert_array_equal(s3.obs[1], [3.0, 7.0])
    np.testing.assert_allclose(s3.last_return[0], 6.0)
    assert s3.last_length[0] == 3
    assert np.isnan(s3.last_return[1])
    np.testing.assert_array_equal(states[3].step_count, [1, 4])


@pytest.mark.timeout(120)
def test_termination_on_the_last_step_is_not_truncated(vec):
    states = _run(vec, [[0, 0]] * (T - 1) + [[1, 0]])
    end = states[-1]
    np.testing.assert_array_equal(end.terminated, [True, False])
    np.testing.assert_array_equal(end.truncated, [False, True])
    np.testing.assert_array_equal(end.last_length, [T, T])


def test_num_envs_must_be_positive():
    with pytest.raises(ValueError, match="num_envs"):
        VecEnv(CounterEnv(), 0)


def test_an_env_that_cannot_switch_physics_says_so():
    """`Env.with_physics`'s default refuses, naming the env and what is allowed; MJX-JAX on an
    MJX-JAX env is the env itself (no copy, nothing rebuilt)."""
    from sirl_jax.envs.loading import with_physics
    from sirl_jax.envs.physics import Physics

    env = CounterEnv()
    assert env.physics_impl == "jax"
    assert with_physics(env, Physics("jax")) is env
    with pytest.raises(ValueError, match="CounterEnv cannot switch its physics.*impl='jax'"):
        env.with_physics(Physics("warp"))
