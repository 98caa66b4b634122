"""Pytrees shared across components.

Shape letters: E envs, B batch, H horizon, O observation size, A action size.
"""

from __future__ import annotations

import jax
from flax import struct


@struct.dataclass
class Batch:
    """B sub-trajectories of H+1 steps from the replay buffer, time-major.

    All steps of one sub-trajectory come from one finished episode.

    Attributes:
      obs: [H+1, B, O] observations s_0..s_H.
      action: [H, B, A] actions a_0..a_{H-1}, in [-1, 1].
      reward: [H, B] rewards r_0..r_{H-1}.
      terminated: [H, B] 1.0 where s_{t+1} is terminal (a fall), else 0.0.
      episode_return: [B] return R of the episode each sub-trajectory came from.
    """

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    terminated: jax.Array
    episode_return: jax.Array
