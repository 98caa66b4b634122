"""Compiled task rollouts shared by tests/test_tasks.py and tests/test_manipulation.py.

One program per task: `VecEnv.reset`, then `episode + extra` steps of a constant action, run on
two variants of the task's model (a jit argument, so one compile serves both): weightless,
holding the keyframe pose (nothing can fall), and limp (no actuator force at all).
"""

import jax
import jax.numpy as jnp

from sirl_jax.envs import VecEnv, make


def weightless(mx):
    """The model without gravity: a robot holding its pose cannot fall."""
    return mx.replace(opt=mx.opt.replace(gravity=jnp.zeros_like(mx.opt.gravity)))


def limp(mx):
    """The model with every actuator's gain and bias zeroed: no actuator force at all."""
    return mx.replace(
        actuator_gainprm=mx.actuator_gainprm.at[:, 0].set(0.0),
        actuator_biasprm=mx.actuator_biasprm.at[:, 1:3].set(0.0),
    )


def _program(env, num_envs: int, length: int):
    def run(mx, key, action):
        v = VecEnv(env.with_model(mx), num_envs)
        start = v.reset(key)

        def body(state, _):
            state = v.step(state, jnp.broadcast_to(action, (num_envs, env.action_size)))
            finite = jnp.all(jnp.isfinite(state.obs), -1) & jnp.all(
                jnp.isfinite(state.final_obs), -1
            )
            trace = {
                "finite": finite,
                "root_z": state.final_obs[:, 2],  # obs starts with qpos
                "final_obs": state.final_obs,
                "qpos": state.physics.qpos,
                "reward": state.reward,
                "terminated": state.terminated,
                "truncated": state.truncated,
                "last_length": state.last_length,
                "step_count": state.step_count,
                "metrics": state.metrics,
            }
            return state, trace

        end, trace = jax.lax.scan(body, start, None, length=length)
        return start, end, trace

    return jax.jit(run)


_CACHE: dict[tuple, tuple] = {}


def hold_and_limp(task_id: str, num_envs: int, episode: int, extra: int):
    """(env, weightless holding run, limp run), each run (start, end, trace [T, E, ...]);
    compiled and run once per argument set, then cached."""
    args = (task_id, num_envs, episode, extra)
    if args not in _CACHE:
        env = make(task_id, episode_length=episode)
        assert VecEnv(env, num_envs).episode_length == episode
        run = _program(env, num_envs, episode + extra)
        key = jax.random.PRNGKey(0)
        hold = jnp.asarray(env.robot.keyframe_action)
        normal = jax.device_get(run(weightless(env.mx), key, hold))
        still = jax.device_get(run(limp(env.mx), key, jnp.zeros(env.action_size)))
        _CACHE[args] = (env, normal, still)
    return _CACHE[args]
