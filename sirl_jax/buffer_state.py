"""The replay buffer's state: what `sirl_jax.buffer.Buffer` stores and keeps track of.

One pytree (`BufferState`) of storage rings, the episode table and per-env bookkeeping of the
running episode; `BufferState.zeros` is the empty buffer. The functions that write and read
it are `Buffer`'s (`sirl_jax/buffer.py`, whose docstring has the storage, recording and
sampling rules; docs/buffer.md).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class BufferState:
    """Replay storage, episode table and per-env episode bookkeeping.

    Absolute positions count entries written by one env since `init`; ring row = position % L.
    Absolute episode numbers count recorded episodes of one env; table slot = number % M.

    Attributes:
      obs: [E, L, O] float32 observations.
      action: [E, L, A] float32 action that led to the entry (NaN in entry 0 of an episode).
      reward: [E, L] float32 reward of that action (NaN in entry 0).
      terminated: [E, L] bool the entry is terminal (a fall).
      truncated: [E, L] bool the entry hit the time limit.
      ep_start: [E, M] int32 absolute position of entry 0 of a recorded episode.
      ep_length: [E, M] int32 entries of a recorded episode (transitions + 1).
      ep_return: [E, M] float32 return R of a recorded episode.
      ep_head: [E] int32 number of the oldest live recorded episode.
      ep_tail: [E] int32 number of episodes recorded so far.
      write_pos: [E] int32 absolute position of the next entry.
      cur_start: [E] int32 absolute position of the running episode's entry 0.
      cur_return: [E] float32 return of the running episode so far.
      cur_discount: [E] float32 discount^k for the running episode's next reward.
      cur_fresh: [E] bool the next `add` starts a new episode.
      r_max: [] float32 reference return for the configured `rmax_mode` (-inf before any).
      r_max_all_time: [] float32 max R over every recorded episode (-inf before any).
      episodes_recorded: [] int32 episodes recorded so far (all envs, evicted ones included).
    """

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    ep_start: jax.Array
    ep_length: jax.Array
    ep_return: jax.Array
    ep_head: jax.Array
    ep_tail: jax.Array
    write_pos: jax.Array
    cur_start: jax.Array
    cur_return: jax.Array
    cur_discount: jax.Array
    cur_fresh: jax.Array
    r_max: jax.Array
    r_max_all_time: jax.Array
    episodes_recorded: jax.Array

    @classmethod
    def zeros(cls, e: int, l: int, m: int, o: int, a: int) -> BufferState:
        """An empty buffer of E envs, L-entry rings and M table slots per env, O-dim
        observations and A-dim actions (`Buffer.init`)."""
        f32, i32 = jnp.float32, jnp.int32
        return cls(
            obs=jnp.zeros((e, l, o), f32),
            action=jnp.zeros((e, l, a), f32),
            reward=jnp.zeros((e, l), f32),
            terminated=jnp.zeros((e, l), bool),
            truncated=jnp.zeros((e, l), bool),
            ep_start=jnp.zeros((e, m), i32),
            ep_length=jnp.zeros((e, m), i32),
            ep_return=jnp.zeros((e, m), f32),
            ep_head=jnp.zeros((e,), i32),
            ep_tail=jnp.zeros((e,), i32),
            write_pos=jnp.zeros((e,), i32),
            cur_start=jnp.zeros((e,), i32),
            cur_return=jnp.zeros((e,), f32),
            cur_discount=jnp.ones((e,), f32),
            cur_fresh=jnp.ones((e,), bool),
            r_max=jnp.full((), -jnp.inf, f32),
            r_max_all_time=jnp.full((), -jnp.inf, f32),
            episodes_recorded=jnp.zeros((), i32),
        )
