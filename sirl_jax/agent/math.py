"""Scalar transforms and the discrete regression of TD-MPC2 (spec §2.1, §2.2).

Values are regressed as a two-hot distribution over `num_bins` bins that are evenly spaced in
symlog space on [vmin, vmax]; decoding takes the expectation in symlog space, then symexp.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def symlog(x: jax.Array) -> jax.Array:
    """sign(x) * ln(1 + |x|)."""
    return jnp.sign(x) * jnp.log1p(jnp.abs(x))


def symexp(x: jax.Array) -> jax.Array:
    """sign(x) * (exp(|x|) - 1), the inverse of `symlog`."""
    return jnp.sign(x) * jnp.expm1(jnp.abs(x))


def bin_centres(num_bins: int, vmin: float, vmax: float) -> jax.Array:
    """[num_bins] bin centres in symlog space."""
    return jnp.linspace(vmin, vmax, num_bins)


def two_hot(x: jax.Array, num_bins: int, vmin: float, vmax: float) -> jax.Array:
    """Two-hot encoding of symlog(x).

    Args:
      x: [...] raw (not symlog) targets.
    Returns:
      [..., num_bins] weights summing to 1. Weight 1 - f goes to bin k = floor(position) and f to
      bin (k + 1) mod num_bins (the wrap only ever receives weight 0, at x' = vmax).
    """
    y = jnp.clip(symlog(x), vmin, vmax)
    pos = (y - vmin) * ((num_bins - 1) / (vmax - vmin))
    k = jnp.floor(pos)
    f = pos - k
    k = k.astype(jnp.int32)
    lo = jax.nn.one_hot(k, num_bins) * (1.0 - f)[..., None]
    hi = jax.nn.one_hot((k + 1) % num_bins, num_bins) * f[..., None]
    return lo + hi


def soft_ce(logits: jax.Array, target: jax.Array) -> jax.Array:
    """Soft cross-entropy -sum_k target_k log_softmax(logits)_k over the last axis: [...]."""
    return -jnp.sum(target * jax.nn.log_softmax(logits, axis=-1), axis=-1)


def two_hot_ce(
    logits: jax.Array, x: jax.Array, num_bins: int, vmin: float, vmax: float
) -> jax.Array:
    """Soft cross-entropy between logits [..., num_bins] and the two-hot of raw targets x [...]."""
    return soft_ce(logits, two_hot(x, num_bins, vmin, vmax))


def decode(logits: jax.Array, vmin: float, vmax: float) -> jax.Array:
    """Decode logits [..., num_bins] to raw scalars [...]: symexp(E_softmax[bin])."""
    bins = bin_centres(logits.shape[-1], vmin, vmax)
    return symexp(jnp.sum(jax.nn.softmax(logits, axis=-1) * bins, axis=-1))


def discount_from_episode_length(
    episode_length: int, denom: float = 5.0, gamma_min: float = 0.95, gamma_max: float = 0.995
) -> float:
    """gamma = clip((T/denom - 1) / (T/denom), gamma_min, gamma_max) (TD-MPC2 heuristic)."""
    if episode_length < 1:
        raise ValueError(f"episode_length must be >= 1, got {episode_length}")
    frac = episode_length / denom
    return float(min(max((frac - 1.0) / frac, gamma_min), gamma_max))
