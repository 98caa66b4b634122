"""The TD-MPC2 world model as pure functions over a params dict (spec §1.2-§1.4).

params = {'encoder', 'dynamics', 'reward', 'policy', 'qs'} (+ 'termination' when episodic) from
`networks.init_params`.
Shapes: leading batch dims [...] are free; Z latent, A action, O observation.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp

from sirl_jax.agent import math as am
from sirl_jax.agent.config import AgentConfig
from sirl_jax.agent.networks import make_modules

LOG_2PI = math.log(2.0 * math.pi)


def squashed_log_likelihood_dims(
    mu: jax.Array, log_std: jax.Array, a: jax.Array, clip: float = 1e-6
) -> jax.Array:
    """Per-dimension log density of a given action a in [-1, 1] under tanh(N(mu, exp(log_std)))
    ([..., A] -> [..., A]; the sum over the last axis is log pi(a)).

    a is clipped to +-(1 - clip) before arctanh; the tanh correction uses the same 1e-6 as `pi`.
    """
    a = jnp.clip(a, -1.0 + clip, 1.0 - clip)
    x = (jnp.arctanh(a) - mu) * jnp.exp(-log_std)
    lp_g = -0.5 * x**2 - log_std - 0.5 * LOG_2PI
    return lp_g - jnp.log(jnp.maximum(0.0, 1.0 - a**2) + 1e-6)


def squashed_log_likelihood(
    mu: jax.Array, log_std: jax.Array, a: jax.Array, clip: float = 1e-6
) -> jax.Array:
    """log pi(a) of an action a in [-1, 1] under tanh(N(mu, exp(log_std))) ([..., A] -> [...])."""
    return jnp.sum(squashed_log_likelihood_dims(mu, log_std, a, clip), axis=-1)


class PolicyOutput(NamedTuple):
    """One reparameterised draw of the squashed-Gaussian prior (spec §1.3): [..., A] / [...]."""

    action: jax.Array  # tanh(mu + sigma * eps)
    mean_action: jax.Array  # tanh(mu)
    mu: jax.Array
    log_std: jax.Array
    eps: jax.Array
    log_prob_gauss: jax.Array  # [...] pre-squash log density
    log_prob: jax.Array  # [...] squashed log density


class WorldModel(NamedTuple):
    """Pure functions of the world model; the planner and losses take this as a collaborator."""

    encode: callable  # (params, obs[..., O]) -> z[..., Z]
    next: callable  # (params, z, a) -> z'
    reward_logits: callable  # (params, z, a) -> [..., num_bins]
    reward: callable  # (params, z, a) -> [...] decoded
    pi: callable  # (params, z, key) -> PolicyOutput
    pi_log_prob: callable  # (params, z, a) -> (log-likelihood [...] of a, log_std [..., A])
    q_logits: callable  # (qs_params, z, a, key | None) -> [num_q, ..., num_bins]
    q_pair: callable  # (qs_params, z, a, key, mode, dropout_key | None) -> [...]
    termination_logit: callable | None = None  # (params, z) -> [...] logit; None unless episodic


def make_world_model(cfg: AgentConfig, action_size: int) -> WorldModel:
    """Builds the pure world-model functions for `cfg` (static) and `action_size`."""
    mods = make_modules(cfg, action_size)
    num_q = cfg.arch.num_q
    lo, hi = cfg.log_std_min, cfg.log_std_max

    def apply(name, params, x):
        return mods[name].apply({"params": params[name]}, x)

    def encode(params, obs):
        return apply("encoder", params, obs)

    def next_(params, z, a):
        return apply("dynamics", params, jnp.concatenate([z, a], axis=-1))

    def reward_logits(params, z, a):
        return apply("reward", params, jnp.concatenate([z, a], axis=-1))

    def reward(params, z, a):
        return am.decode(reward_logits(params, z, a), cfg.vmin, cfg.vmax)

    def pi_head(params, z):
        mu, raw = jnp.split(apply("policy", params, z), 2, axis=-1)
        log_std = lo + 0.5 * (hi - lo) * (jnp.tanh(raw) + 1.0)
        return mu, log_std

    def pi(params, z, key):
        mu, log_std = pi_head(params, z)
        eps = jax.random.normal(key, mu.shape, mu.dtype)
        action = jnp.tanh(mu + jnp.exp(log_std) * eps)
        lp_g = jnp.sum(-0.5 * eps**2 - log_std, axis=-1) - 0.5 * LOG_2PI * action_size
        lp_s = lp_g - jnp.sum(jnp.log(jnp.maximum(0.0, 1.0 - action**2) + 1e-6), axis=-1)
        return PolicyOutput(action, jnp.tanh(mu), mu, log_std, eps, lp_g, lp_s)

    def pi_log_prob(params, z, a):
        # Log-likelihood of a given action a in [-1, 1] under the squashed Gaussian (spec §5.2).
        mu, log_std = pi_head(params, z)
        return squashed_log_likelihood(mu, log_std, a), log_std

    def q_member(q_params, za, dropout_key):
        rngs = None if dropout_key is None else {"dropout": dropout_key}
        return mods["q"].apply(
            {"params": q_params}, za, deterministic=dropout_key is None, rngs=rngs
        )

    def q_subset(qs_params, z, a, dropout_key):
        """Applies every member present in qs_params (leading axis M): [M, ..., num_bins]."""
        za = jnp.concatenate([z, a], axis=-1)
        m = jax.tree_util.tree_leaves(qs_params)[0].shape[0]
        if dropout_key is None:
            return jax.vmap(lambda p: q_member(p, za, None))(qs_params)
        keys = jax.random.split(dropout_key, m)
        return jax.vmap(lambda p, k: q_member(p, za, k))(qs_params, keys)

    def q_logits(qs_params, z, a, dropout_key=None):
        return q_subset(qs_params, z, a, dropout_key)

    def q_pair(qs_params, z, a, key, mode, dropout_key=None):
        # Two distinct heads, one draw per call shared across batch and time (spec §1.4).
        idx = jax.random.choice(key, num_q, (2,), replace=False)
        pair = jax.tree_util.tree_map(lambda p: p[idx], qs_params)
        q = am.decode(q_subset(pair, z, a, dropout_key), cfg.vmin, cfg.vmax)
        if mode == "min":
            return jnp.minimum(q[0], q[1])
        if mode == "avg":
            return 0.5 * (q[0] + q[1])
        raise ValueError(f"mode={mode!r} is not allowed; choose 'min' or 'avg'")

    def termination_logit(params, z):
        # Logit of P(terminated) of the state whose latent is z; sigmoid > 0.5 counts as terminal.
        return apply("termination", params, z)[..., 0]

    return WorldModel(
        encode,
        next_,
        reward_logits,
        reward,
        pi,
        pi_log_prob,
        q_logits,
        q_pair,
        termination_logit if cfg.episodic else None,
    )
