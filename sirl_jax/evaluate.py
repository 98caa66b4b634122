"""Evaluation episodes: the planner and the policy prior alone, both in eval mode.

N episodes run in parallel on a fresh `VecEnv(env, N)` for up to T steps under one
`lax.while_loop` that stops once every episode has ended (the steps after it would add nothing);
the first episode of each env counts (a terminated one is not restarted). An
episode whose physics blew up ends there with a NaN return: it is counted in
`eval/<prefix>_blowups` and left out of the means (all of them NaN if every episode blew up). The
returned R_max lets a shell plot the policy's return against the best return in the buffer
(the TDMPBC paper's "training phenomenon" figure).

Shape letters: N episodes (eval envs), O observation, A action.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from sirl_jax.envs.base import Env, VecEnv


def _rollout(env: Env, num_episodes: int, act: Callable, aux0, key: jax.Array):
    """The first episode of each of N fresh envs under `act(env_state, aux, key)`.

    Returns [N] returns (NaN for a blown-up episode), [N] lengths and {term: [N] mean of the
    reward term over the episode}.
    """
    vec = VecEnv(env, num_episodes)
    key_reset, key_run = jax.random.split(key)
    zeros = jnp.zeros((num_episodes,), jnp.float32)
    names = tuple(env.metric_names())

    def body(carry, key_t):
        env_state, aux, ended, ret, length, terms = carry
        action, aux = act(env_state, aux, key_t)
        nxt = vec.step(env_state, action)
        done = nxt.terminated | nxt.truncated
        new = done & ~ended
        ret = jnp.where(new, nxt.last_return, ret)
        ret = jnp.where(nxt.blowup & ~ended, jnp.nan, ret)
        length = jnp.where(new, nxt.last_length.astype(jnp.float32), length)
        terms = {n: terms[n] + jnp.where(ended, 0.0, nxt.metrics[n]) for n in names}
        return (nxt, aux, ended | done | nxt.blowup, ret, length, terms), None

    init = (vec.reset(key_reset), aux0, jnp.zeros_like(zeros, bool), zeros, zeros,
            {n: zeros for n in names})  # fmt: skip
    keys = jax.random.split(key_run, env.episode_length)

    def running(loop):  # stop once every episode has ended: the steps after add nothing
        t, carry = loop
        return (t < env.episode_length) & ~jnp.all(carry[2])

    def step(loop):
        t, carry = loop
        return t + 1, body(carry, keys[t])[0]

    _, carry = jax.lax.while_loop(running, step, (jnp.int32(0), init))
    _, _, _, returns, lengths, terms = carry
    return returns, lengths, {n: v / jnp.maximum(lengths, 1.0) for n, v in terms.items()}


def _summary(prefix: str, bar: float | None, returns, lengths, terms) -> dict[str, jax.Array]:
    intact = jnp.isfinite(returns)

    def mean(x):
        return jnp.sum(jnp.where(intact, x, 0.0)) / jnp.where(intact.any(), intact.sum(), jnp.nan)

    avg = mean(returns)
    success = mean(returns >= bar) if bar is not None else jnp.float32(jnp.nan)
    return {
        f"eval/{prefix}_return": avg,
        f"eval/{prefix}_return_std": jnp.sqrt(mean(jnp.square(returns - avg))),
        f"eval/{prefix}_length": mean(lengths),
        f"eval/{prefix}_success": jnp.asarray(success, jnp.float32),
        f"eval/{prefix}_blowups": jnp.sum(~intact, dtype=jnp.int32),
        **{f"eval/{prefix}_term/{n}": mean(v) for n, v in terms.items()},
    }


def _check_episodes(num_episodes: int) -> None:
    if num_episodes < 1:
        raise ValueError(f"num_episodes={num_episodes!r} is invalid; allowed: an int >= 1")


def make_random_evaluate(env: Env, num_episodes: int, action: str = "uniform") -> Callable:
    """Builds `evaluate(key) -> metrics` of a baseline policy: `action="uniform"` (the random
    policy, metrics eval/random_*) or `"zero"` (every action 0, i.e. each actuator held at the
    middle of its range; metrics eval/zero_*), as `make_evaluate`'s."""
    _check_episodes(num_episodes)
    if action not in ("uniform", "zero"):
        raise ValueError(f"action={action!r} is invalid; allowed: 'uniform', 'zero'")
    shape = (num_episodes, env.action_size)

    def act(env_state, aux, k):
        if action == "zero":
            return jnp.zeros(shape, jnp.float32), aux
        return jax.random.uniform(k, shape, minval=-1.0, maxval=1.0), aux

    prefix = "random" if action == "uniform" else "zero"

    def evaluate(key: jax.Array) -> dict[str, jax.Array]:
        return _summary(prefix, env.success_bar, *_rollout(env, num_episodes, act, None, key))

    return evaluate


def make_evaluate(env: Env, agent, num_episodes: int, buffer) -> Callable:
    """Builds `evaluate(state, key) -> metrics` for a `TrainState`.

    Metrics ([] arrays): eval/{planner,policy}_{return,return_std,length,success}, with success
    the fraction of episodes whose return reaches the task's success bar (NaN without one);
    eval/{planner,policy}_term/<name>, each reward term's mean over the episodes' steps;
    eval/{planner,policy}_blowups, episodes cut short by a physics blow-up (left out of the
    means); and eval/r_max (the buffer's R_max). The planner entries are absent when
    `agent.cfg.plans` is False (no planner: TD-MPC2 without MPC, or FastTD3).
    """
    _check_episodes(num_episodes)
    bar = env.success_bar

    def evaluate(state, key: jax.Array) -> dict[str, jax.Array]:
        key_plan, key_policy = jax.random.split(key)

        def plan(env_state, planner, k):
            return agent.plan(state.agent, planner, env_state.obs, env_state.first, k, True)

        def policy(env_state, planner, k):
            return agent.act_policy(state.agent, env_state.obs, k, True), planner

        planner0 = agent.init_planner(num_episodes)
        metrics = {"eval/r_max": buffer.r_max(state.buffer)}
        if agent.cfg.plans:
            rollout = _rollout(env, num_episodes, plan, planner0, key_plan)
            metrics.update(_summary("planner", bar, *rollout))
        rollout = _rollout(env, num_episodes, policy, planner0, key_policy)
        metrics.update(_summary("policy", bar, *rollout))
        return metrics

    return evaluate
