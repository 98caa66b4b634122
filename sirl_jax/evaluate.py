"""Evaluation episodes: the planner and the policy prior alone, both in eval mode.

N episodes run in parallel on a fresh `VecEnv(env, N)` for exactly T steps under one
`lax.scan`; the first episode of each env counts (a terminated one is not restarted). The
returned R_max lets a shell plot the policy's return against the best return in the buffer
(the TDMPBC paper's "training phenomenon" figure).

Shape letters: N episodes (eval envs), O observation, A action.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from sirl_jax.envs.base import Env, VecEnv


def make_evaluate(env: Env, agent, num_episodes: int, buffer) -> Callable:
    """Builds `evaluate(state, key) -> metrics` for a `TrainState`.

    Metrics ([] arrays): eval/{planner,policy}_{return,return_std,length,success}, with success
    the fraction of episodes whose return reaches the task's success bar (NaN without one),
    and eval/r_max (the buffer's R_max). The planner entries are absent when `agent.cfg.mpc`
    is False (the agent never plans then).
    """
    if num_episodes < 1:
        raise ValueError(f"num_episodes={num_episodes!r} is invalid; allowed: an int >= 1")
    vec = VecEnv(env, num_episodes)
    horizon = env.episode_length
    bar = env.success_bar

    def rollout(act, key):
        """Returns [N] returns and lengths of the first episode of each eval env."""
        key_reset, key_run = jax.random.split(key)
        env_state = vec.reset(key_reset)
        zeros = jnp.zeros((num_episodes,), jnp.float32)

        def body(carry, key_t):
            env_state, aux, ended, ret, length = carry
            action, aux = act(env_state, aux, key_t)
            nxt = vec.step(env_state, action)
            done = nxt.terminated | nxt.truncated
            new = done & ~ended
            ret = jnp.where(new, nxt.last_return, ret)
            length = jnp.where(new, nxt.last_length.astype(jnp.float32), length)
            return (nxt, aux, ended | done, ret, length), None

        init = (env_state, agent.init_planner(num_episodes), jnp.zeros_like(zeros, bool))
        carry, _ = jax.lax.scan(body, (*init, zeros, zeros), jax.random.split(key_run, horizon))
        return carry[3], carry[4]

    def summary(prefix: str, returns: jax.Array, lengths: jax.Array) -> dict[str, jax.Array]:
        success = jnp.mean(returns >= bar) if bar is not None else jnp.float32(jnp.nan)
        return {
            f"eval/{prefix}_return": jnp.mean(returns),
            f"eval/{prefix}_return_std": jnp.std(returns),
            f"eval/{prefix}_length": jnp.mean(lengths),
            f"eval/{prefix}_success": jnp.asarray(success, jnp.float32),
        }

    def evaluate(state, key: jax.Array) -> dict[str, jax.Array]:
        key_plan, key_policy = jax.random.split(key)

        def plan(env_state, planner, k):
            return agent.plan(state.agent, planner, env_state.obs, env_state.first, k, True)

        def policy(env_state, planner, k):
            return agent.act_policy(state.agent, env_state.obs, k, True), planner

        metrics = {"eval/r_max": buffer.r_max(state.buffer)}
        if agent.cfg.mpc:
            metrics.update(summary("planner", *rollout(plan, key_plan)))
        metrics.update(summary("policy", *rollout(policy, key_policy)))
        return metrics

    return evaluate
