"""FastTD3's building blocks: PyTorch-initialised MLPs, the categorical projection of the
distributional critic, and the running observation normaliser (`fasttd3.py` assembles them)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
from flax import struct


def _uniform(bound: float):
    def init(key, shape, dtype=jnp.float32):
        return jax.random.uniform(key, shape, dtype, -bound, bound)

    return init


class TorchDense(nn.Module):
    """Dense with PyTorch's nn.Linear init: kernel and bias ~ U(+-1/sqrt(fan_in)); with
    `normal_std`, kernel ~ N(0, normal_std^2) and bias 0 (FastTD3's actor output layer)."""

    features: int
    normal_std: float | None = None

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        fan_in = x.shape[-1]
        bound = 1.0 / math.sqrt(fan_in)
        if self.normal_std is None:
            k_init, b_init = _uniform(bound), _uniform(bound)
        else:
            k_init, b_init = nn.initializers.normal(self.normal_std), nn.initializers.zeros
        kernel = self.param("kernel", k_init, (fan_in, self.features))
        bias = self.param("bias", b_init, (self.features,))
        return x @ kernel + bias


class ReluMLP(nn.Module):
    """Hidden TorchDense + ReLU layers ('hidden_i'), then an output TorchDense ('out')."""

    hidden: Sequence[int]
    out: int
    out_normal_std: float | None = None
    tanh: bool = False

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for i, width in enumerate(self.hidden):
            x = jax.nn.relu(TorchDense(width, name=f"hidden_{i}")(x))
        x = TorchDense(self.out, self.out_normal_std, name="out")(x)
        return jnp.tanh(x) if self.tanh else x


def widths(h: int) -> tuple[int, int, int]:
    """FastTD3's MLP widths from its hidden_dim: h, h // 2, h // 4."""
    return h, h // 2, h // 4


def project(probs, reward, bootstrap, discount, support, v_min: float, v_max: float):
    """Categorical (C51) projection of r + bootstrap * discount * z onto `support`.

    Each atom's mass p_i goes to the two support points around its shifted, clipped value b_i
    (in atom units), in proportion to closeness; an exact hit keeps all of it. This is
    FastTD3's `projection` (its l == u adjustment gives the same split).

    Args:
      probs: [B, N] next-state probabilities; reward, bootstrap, discount: [B] (or []).
      support: [N] atoms linspace(v_min, v_max, N).
    Returns:
      [B, N] projected probabilities (rows sum to those of `probs`).
    """
    n = support.shape[0]
    delta = (v_max - v_min) / (n - 1)
    tz = jnp.reshape(reward, (-1, 1)) + jnp.reshape(bootstrap * discount, (-1, 1)) * support
    tz = jnp.broadcast_to(jnp.clip(tz, v_min, v_max), probs.shape)
    b = (tz - v_min) / delta
    lower = jnp.clip(jnp.floor(b), 0, n - 1)
    frac = b - lower  # in [0, 1); 0 at an exact hit and at v_max
    lo_i, hi_i = lower.astype(jnp.int32), jnp.minimum(lower.astype(jnp.int32) + 1, n - 1)

    def row(p, lo, hi, f):
        return jnp.zeros((n,), p.dtype).at[lo].add(p * (1.0 - f)).at[hi].add(p * f)

    return jax.vmap(row)(probs, lo_i, hi_i, frac)


@struct.dataclass
class ObsNorm:
    """FastTD3's EmpiricalNormalization: running mean / variance over every batch seen."""

    mean: jax.Array  # [O]
    var: jax.Array  # [O]
    count: jax.Array  # [] float32 rows seen

    @classmethod
    def init(cls, size: int) -> ObsNorm:
        return cls(jnp.zeros((size,)), jnp.ones((size,)), jnp.zeros(()))

    def update(self, x: jax.Array) -> ObsNorm:
        """Chan et al.'s parallel update with the batch x [B, O] (population variance)."""
        n = jnp.float32(x.shape[0])
        batch_mean, batch_var = jnp.mean(x, axis=0), jnp.var(x, axis=0)
        total = self.count + n
        mean = self.mean + (batch_mean - self.mean) * (n / total)
        m2 = (self.var * self.count + batch_var * n
              + jnp.square(batch_mean - mean) * (self.count * n / total))  # fmt: skip
        return ObsNorm(mean, m2 / total, total)

    def __call__(self, x: jax.Array, eps: float) -> jax.Array:
        return (x - self.mean) / (jnp.sqrt(self.var) + eps)
