"""MPPI in latent space (spec §3), batched over E environments.

Shapes: E envs, H horizon, N samples, P policy trajectories, K elites, A action, Z latent.
The world model is a collaborator (`PlannerModel`), so a test can plan on a fake model.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from sirl_jax.agent.config import AgentConfig


@struct.dataclass
class PlannerState:
    """prev_mean: [E, H, A] final MPPI mean of the previous step, per env."""

    prev_mean: jax.Array


class PlannerModel(NamedTuple):
    """What MPPI needs from a world model; every function is pure in (params, ...)."""

    encode: Callable  # (params, obs[O]) -> z[Z]
    next: Callable  # (params, z[N, Z], a[N, A]) -> z[N, Z]
    reward: Callable  # (params, z[N, Z], a[N, A]) -> [N]
    pi_sample: Callable  # (params, z[N, Z], key) -> a[N, A], a stochastic policy sample
    q_avg: Callable  # (params, z[N, Z], a[N, A], key) -> [N]
    termination: Callable | None = None  # (params, z[N, Z]) -> logit [N]; None: no masking


class Planner(NamedTuple):
    init: Callable  # (num_envs) -> PlannerState
    plan: Callable  # (params, PlannerState, obs[E, O], first[E], key, eval_mode) -> (a, state)


def estimate_value(
    model: PlannerModel, params, z: jax.Array, actions: jax.Array, key: jax.Array, discount: float
) -> jax.Array:
    """V = sum_t g^t R(z_t, a_t) + g^H Qavg(z_H, a_H ~ pi); z [N, Z], actions [H, N, A] -> [N].

    With model.termination (episodic), a sample whose predicted P(terminal | z_{t+1}) > 0.5
    keeps R(z_t, a_t), the reward of the transition into the terminal state, and drops every
    later reward and the terminal Q (the reference's (1 - termination) mask, set after the
    reward of step t is added and never cleared).
    """
    H = actions.shape[0]
    k_pi, k_q = jax.random.split(key)
    gammas = discount ** jnp.arange(H, dtype=jnp.float32)
    n = z.shape[0]

    def step(carry, xs):
        z_t, ret, alive = carry  # alive [N]: 1.0 until a termination is predicted
        a_t, g_t = xs
        ret = ret + g_t * alive * model.reward(params, z_t, a_t)
        z_next = model.next(params, z_t, a_t)
        if model.termination is not None:
            ended = jax.nn.sigmoid(model.termination(params, z_next)) > 0.5
            alive = jnp.where(ended, 0.0, alive)
        return (z_next, ret, alive), None

    # Without a head alive stays 1.0, and multiplying by 1.0 is exact: the unmasked values.
    (z_H, ret, alive), _ = jax.lax.scan(step, (z, jnp.zeros(n), jnp.ones(n)), (actions, gammas))
    a_H = model.pi_sample(params, z_H, k_pi)
    q = alive * model.q_avg(params, z_H, a_H, k_q)
    return ret + discount**H * q


def mppi_update(
    cfg: AgentConfig, values: jax.Array, actions: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """One MPPI refit from values [N] of sequences actions [H, N, A].

    Returns:
      mean [H, A], std [H, A] (clamped to [min_std, max_std]), elite actions [H, K, A], scores [K].
    """
    # The reference's nan_to_num(0): NaN -> 0, +-inf -> the largest finite float32 of that sign.
    values = jnp.nan_to_num(values, nan=0.0)
    elite_v, idx = jax.lax.top_k(values, cfg.num_elites)
    elites = actions[:, idx]
    scores = jnp.exp(cfg.temperature * (elite_v - elite_v[0]))  # top_k is sorted: [0] is the max
    scores = scores / jnp.sum(scores)
    mean = jnp.einsum("k,hka->ha", scores, elites)
    var = jnp.einsum("k,hka->ha", scores, (elites - mean[:, None]) ** 2)
    std = jnp.clip(jnp.sqrt(var), cfg.min_std, cfg.max_std)
    return mean, std, elites, scores


def run_mppi(
    cfg: AgentConfig,
    value_fn: Callable,
    mean: jax.Array,
    std: jax.Array,
    pi_actions: jax.Array,
    noise: jax.Array,
    keys: jax.Array,
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """MPPI iterations as a scan over pre-sampled noise.

    Args:
      value_fn: (actions [H, N, A], key) -> values [N].
      mean, std: [H, A] initial distribution. pi_actions: [H, P, A], fixed across iterations.
      noise: [I, H, N - P, A] standard normal. keys: [I, 2] one value key per iteration.
    Returns:
      final mean [H, A], std [H, A], elites [H, K, A], scores [K].
    """
    H, A = mean.shape
    K = cfg.num_elites

    def iteration(carry, xs):
        mean, std, _, _ = carry
        eps, key = xs
        sampled = jnp.clip(mean[:, None] + std[:, None] * eps, -1.0, 1.0)
        actions = jnp.concatenate([pi_actions, sampled], axis=1)
        return mppi_update(cfg, value_fn(actions, key), actions), None

    init = (mean, std, jnp.zeros((H, K, A), mean.dtype), jnp.zeros((K,), mean.dtype))
    out, _ = jax.lax.scan(iteration, init, (noise, keys))
    return out


def warm_start(prev_mean: jax.Array, first: jax.Array) -> jax.Array:
    """Initial MPPI mean [H, A]: prev_mean shifted one step (last step 0), or 0 when first."""
    shifted = jnp.concatenate([prev_mean[1:], jnp.zeros_like(prev_mean[:1])], axis=0)
    return jnp.where(first, jnp.zeros_like(prev_mean), shifted)


def make_planner(
    cfg: AgentConfig,
    action_size: int,
    discount: float,
    iterations: int,
    model: PlannerModel,
    env_chunk: int = 0,
) -> Planner:
    """MPPI planner over `model`; `iterations` is the already-adjusted count.

    env_chunk: 0 vmaps over all envs; k > 0 maps sequentially over chunks of k envs.
    """
    H, A, N, P = cfg.horizon, action_size, cfg.num_samples, cfg.num_pi_trajs

    def init(num_envs: int) -> PlannerState:
        return PlannerState(prev_mean=jnp.zeros((num_envs, H, A), jnp.float32))

    def policy_trajectories(params, z, key):
        """[H, P, A] stochastic policy rollouts from z [Z], drawn once per step."""
        keys = jax.random.split(key, H)

        def step(z_t, k):
            a_t = model.pi_sample(params, z_t, k)
            return model.next(params, z_t, a_t), a_t

        _, acts = jax.lax.scan(step, jnp.broadcast_to(z, (P, z.shape[-1])), keys)
        return acts

    def plan_one(params, prev_mean, first, obs, key, eval_mode):
        k_pi, k_noise, k_iter, k_sel, k_act = jax.random.split(key, 5)
        z = model.encode(params, obs)
        if P > 0:
            pi_actions = policy_trajectories(params, z, k_pi)
        else:
            pi_actions = jnp.zeros((H, 0, A), jnp.float32)
        mean = warm_start(prev_mean, first)
        std = jnp.full((H, A), cfg.max_std, jnp.float32)  # std is never warm-started
        noise = jax.random.normal(k_noise, (iterations, H, N - P, A))
        z_n = jnp.broadcast_to(z, (N, z.shape[-1]))

        def value_fn(actions, k):
            return estimate_value(model, params, z_n, actions, k, discount)

        iter_keys = jax.random.split(k_iter, iterations)
        mean, std, elites, scores = run_mppi(cfg, value_fn, mean, std, pi_actions, noise, iter_keys)
        idx = jax.random.categorical(k_sel, jnp.log(scores))  # Gumbel-max, temperature 1
        action = elites[0, idx]
        if not eval_mode:
            action = action + std[0] * jax.random.normal(k_act, (A,))
        return jnp.clip(action, -1.0, 1.0), mean

    def plan(params, state: PlannerState, obs, first, key, eval_mode: bool = False):
        """obs [E, O], first [E] bool -> (action [E, A], PlannerState). eval_mode is static."""
        keys = jax.random.split(key, obs.shape[0])
        one = lambda xs: plan_one(params, *xs, eval_mode)
        xs = (state.prev_mean, first, obs, keys)
        if env_chunk > 0:
            # Sequential over chunks of envs (a CPU option: keeps activations cache-sized).
            actions, means = jax.lax.map(one, xs, batch_size=env_chunk)
        else:
            actions, means = jax.vmap(one)(xs)
        return actions, PlannerState(prev_mean=means)

    return Planner(init, plan)
