"""Device-resident replay buffer of whole episodes, with per-trajectory returns (TDMPBC).

Storage follows TD-MPC2's episode format, one entry per observation, each stored once:
entry 0 of an episode is its reset observation (action and reward NaN, flags False), entry k >= 1
is (s_k, a_{k-1}, r_{k-1}, terminated_{k-1}, truncated_{k-1}). An episode of T transitions takes
T + 1 entries. Each env writes into its own ring of L = capacity // E entries, so `capacity`
counts entries as TD-MPC2's `LazyTensorStorage` does (one per transition plus one reset entry per
episode). The first `add` of an episode writes two entries (reset obs, then s_1); every other `add`
writes one.

An episode enters the episode table [E, M] (start, length, return R) when it ends, if it has
more than H + 1 entries (HumanoidBench fork rule) and still fits in its ring. A shorter one is
dropped and its ring space is reused. A recorded episode leaves the table as soon as the ring
overwrites its first entry; since each env's episodes are recorded and evicted in order, the live
ones are the contiguous range [ep_head, ep_tail) of that env's table ring. One eviction check per
`add` suffices: an `add` moves the write position by at most 2 and recorded episodes are at least
H + 2 >= 3 entries apart. M = L // (H + 2) + 1 bounds the number of live recorded episodes.

Sampling (`sampling`): "episode" is TD-MPC2's `SliceSampler`: the episode is drawn uniformly
among the live recorded episodes of all envs, then the start uniformly among its length - H
windows of H + 1 entries, so a window of a short episode is drawn more often than one of a long
episode. "transition" draws uniformly among all windows of all live recorded episodes (an
episode with probability proportional to its number of windows), as FastTD3's replay draws
transitions. Either way a window never crosses an episode boundary and never touches a running
episode.

R (`discount` = 1: undiscounted sum of the episode's rewards; else sum of discount^k r_k) is
recorded when the episode ends. `r_max`: "in_buffer" is the masked max of R over live table
entries (recomputed whenever an episode is recorded or evicted, so it drops when the best one
leaves); "all_time" is the running max over every recorded episode, evicted ones included.
Both count recorded episodes only and are -inf before the first one.

Shape letters: E envs, L entries per env ring, M table slots per env, B batch, H horizon,
O observation size, A action size.
"""

from __future__ import annotations

import dataclasses
import numbers

import jax
import jax.numpy as jnp

from sirl_jax.agent.config import RMAX_MODES
from sirl_jax.buffer_state import BufferState
from sirl_jax.types import Batch

__all__ = ["RMAX_MODES", "SAMPLINGS", "Buffer", "BufferState", "make_buffer"]
SAMPLINGS = ("episode", "transition")
"""`Buffer.sampling`: TD-MPC2's episode-uniform slices, or FastTD3's uniform transitions."""


@dataclasses.dataclass(frozen=True)
class Buffer:
    """Static configuration and the pure buffer functions. Build with `make_buffer`."""

    capacity: int
    num_envs: int
    obs_size: int
    action_size: int
    horizon: int
    batch_size: int
    discount: float = 1.0
    rmax_mode: str = "in_buffer"
    sampling: str = "episode"

    @property
    def ring_size(self) -> int:
        """L, entries per env ring."""
        return self.capacity // self.num_envs

    @property
    def table_size(self) -> int:
        """M, episode-table slots per env (live recorded episodes are >= H + 2 entries)."""
        return self.ring_size // (self.horizon + 2) + 1

    @property
    def nbytes(self) -> int:
        """Bytes `init` allocates (storage, episode table and counters)."""
        shapes = jax.eval_shape(self.init)
        return sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(shapes))

    def describe(self) -> str:
        """One line: capacity, bytes per transition, total size."""
        total = self.num_envs * self.ring_size
        return (
            f"replay buffer: {total:,} entries ({self.num_envs} envs x {self.ring_size:,}), "
            f"{self.nbytes / total:.1f} B/transition, {self.nbytes / 1e9:.3f} GB, "
            f"H={self.horizon}, B={self.batch_size}, R_max={self.rmax_mode}, "
            f"discount={self.discount}, {self.sampling}-uniform sampling"
        )

    def init(self) -> BufferState:
        """An empty buffer (zeros). Pure: works under `jit` and `vmap` over seeds."""
        return BufferState.zeros(
            self.num_envs, self.ring_size, self.table_size, self.obs_size, self.action_size
        )

    def add(
        self, state: BufferState, obs: jax.Array, action: jax.Array, reward: jax.Array,
        next_obs: jax.Array, terminated: jax.Array, truncated: jax.Array,
        discard: jax.Array | None = None,
    ) -> BufferState:  # fmt: skip
        """Adds one transition per env.

        Args:
          state: the buffer.
          obs: [E, O] s_t (the reset observation when the previous `add` ended the episode).
          action: [E, A] a_t.
          reward: [E] r_t.
          next_obs: [E, O] s_{t+1} before any auto-reset (`EnvState.final_obs`).
          terminated: [E] bool, s_{t+1} is terminal.
          truncated: [E] bool, the time limit was hit at s_{t+1}.
          discard: [E] bool or None: the env's transition is not written and its running
            episode is dropped unrecorded (ring space reused, no R, not in R_max); the env's
            next `add` starts a new episode. For a physics blow-up (`EnvState.blowup`).

        Returns:
          The updated buffer. The episode is recorded when terminated | truncated.
        """
        self._check_add_shapes(obs, action, reward, next_obs, terminated, truncated)
        e, l, m, h = self.num_envs, self.ring_size, self.table_size, self.horizon
        env = jnp.arange(e)
        terminated = jnp.asarray(terminated, bool)
        truncated = jnp.asarray(truncated, bool)
        reward = jnp.asarray(reward, jnp.float32)
        discard = jnp.zeros((e,), bool) if discard is None else jnp.asarray(discard, bool)
        fresh = state.cur_fresh
        cur_start = jnp.where(fresh, state.write_pos, state.cur_start)
        # Row L is out of range: mode="drop" skips the reset entry unless the episode starts
        # here, and both entries of a discarded transition.
        first_row = jnp.where(fresh & ~discard, state.write_pos % l, l)
        step_pos = state.write_pos + fresh.astype(jnp.int32)
        envs2 = jnp.concatenate([env, env])
        rows2 = jnp.concatenate([first_row, jnp.where(discard, l, step_pos % l)])

        def write(buf, first, step):
            return buf.at[envs2, rows2].set(jnp.concatenate([first, step]), mode="drop")

        no_flag = jnp.zeros((e,), bool)
        new_pos = step_pos + 1
        discount_k = jnp.where(fresh, 1.0, state.cur_discount)
        cur_return = jnp.where(fresh, 0.0, state.cur_return) + discount_k * reward
        done = (terminated | truncated) & ~discard
        length = new_pos - cur_start

        # Evict the oldest recorded episode once the ring has overwritten its entry 0.
        head_start = state.ep_start[env, state.ep_head % m]
        written_to = jnp.where(discard, state.write_pos, new_pos)  # a discard writes nothing
        evict = (state.ep_head < state.ep_tail) & (head_start < written_to - l)
        ep_head = state.ep_head + evict.astype(jnp.int32)

        keep = done & (length >= h + 2) & (length <= l)
        slot = jnp.where(keep, state.ep_tail % m, m)
        ep_start = state.ep_start.at[env, slot].set(cur_start, mode="drop")
        ep_length = state.ep_length.at[env, slot].set(length, mode="drop")
        ep_return = state.ep_return.at[env, slot].set(cur_return, mode="drop")
        ep_tail = state.ep_tail + keep.astype(jnp.int32)
        # HumanoidBench drops episodes of <= H + 1 entries: reuse their ring space, and that of
        # a discarded episode.
        write_pos = jnp.where((done & (length < h + 2)) | discard, cur_start, new_pos)

        new_best = jnp.max(jnp.where(keep, cur_return, -jnp.inf))
        r_max_all_time = jnp.maximum(state.r_max_all_time, new_best)
        if self.rmax_mode == "all_time":
            r_max = r_max_all_time
        else:
            # The [E, M] masked max only changes when an episode enters or leaves the table.
            r_max = jax.lax.cond(
                jnp.any(evict | keep),
                lambda: _live_max(ep_return, ep_head, ep_tail),
                lambda: state.r_max,
            )

        return state.replace(
            obs=write(state.obs, obs, next_obs),
            action=write(state.action, jnp.full_like(action, jnp.nan), action),
            reward=write(state.reward, jnp.full_like(reward, jnp.nan), reward),
            terminated=write(state.terminated, no_flag, terminated),
            truncated=write(state.truncated, no_flag, truncated),
            ep_start=ep_start,
            ep_length=ep_length,
            ep_return=ep_return,
            ep_head=ep_head,
            ep_tail=ep_tail,
            write_pos=write_pos,
            cur_start=cur_start,
            cur_return=cur_return,
            cur_discount=discount_k * self.discount,
            cur_fresh=done | discard,
            r_max=r_max,
            r_max_all_time=r_max_all_time,
            episodes_recorded=state.episodes_recorded + jnp.sum(keep, dtype=jnp.int32),
        )

    def sample(self, state: BufferState, key: jax.Array) -> Batch:
        """B windows of H + 1 consecutive entries, each within one live recorded episode.

        The episode is drawn uniformly among live recorded episodes, then the window start
        uniformly within it. Only meaningful when `can_sample(state)`; before that the batch
        holds zeros and arbitrary entries.

        Returns:
          `Batch` (time-major): obs [H+1, B, O]; action [H, B, A], reward [H, B] and
          terminated [H, B] (float 0/1) from entries 1..H of the windows; episode_return [B].
        """
        e, l, m, h = self.num_envs, self.ring_size, self.table_size, self.horizon
        b = self.batch_size
        key_episode, key_start = jax.random.split(key)
        if self.sampling == "transition":
            env, slot, offset = self._window_uniform(state, key_episode)
        else:
            count = state.ep_tail - state.ep_head
            cum = jnp.cumsum(count)
            u = jax.random.randint(key_episode, (b,), 0, jnp.maximum(cum[-1], 1))
            env = jnp.minimum(jnp.searchsorted(cum, u, side="right"), e - 1)
            slot = (state.ep_head[env] + u - (cum[env] - count[env])) % m
            length = state.ep_length[env, slot]
            offset = jax.random.randint(key_start, (b,), 0, jnp.maximum(length - h, 1))
        pos = state.ep_start[env, slot] + offset
        rows = (pos[None, :] + jnp.arange(h + 1)[:, None]) % l
        envs = jnp.broadcast_to(env[None, :], rows.shape)
        return Batch(
            obs=state.obs[envs, rows],
            action=state.action[envs[1:], rows[1:]],
            reward=state.reward[envs[1:], rows[1:]],
            terminated=state.terminated[envs[1:], rows[1:]].astype(jnp.float32),
            episode_return=state.ep_return[env, slot],
        )

    def _window_uniform(self, state: BufferState, key: jax.Array):
        """(env, slot, offset) [B] of windows drawn uniformly among all windows of the live
        recorded episodes: a slot is live when it lies in its env's [ep_head, ep_tail)."""
        m, h = self.table_size, self.horizon
        rel = (jnp.arange(m)[None, :] - state.ep_head[:, None]) % m  # [E, M]
        live = rel < (state.ep_tail - state.ep_head)[:, None]
        windows = jnp.where(live, jnp.maximum(state.ep_length - h, 1), 0).reshape(-1)
        cum = jnp.cumsum(windows)
        u = jax.random.randint(key, (self.batch_size,), 0, jnp.maximum(cum[-1], 1))
        flat = jnp.minimum(jnp.searchsorted(cum, u, side="right"), cum.shape[0] - 1)
        return flat // m, flat % m, u - (cum[flat] - windows[flat])

    def can_sample(self, state: BufferState) -> jax.Array:
        """[] bool, at least one live recorded (sampleable) episode."""
        return self.num_episodes(state) > 0

    def r_max(self, state: BufferState) -> jax.Array:
        """[] float32 R_max for `rmax_mode`; -inf before the first recorded episode."""
        return state.r_max

    def num_episodes(self, state: BufferState) -> jax.Array:
        """[] int32 live recorded episodes (the ones `sample` draws from)."""
        return jnp.sum(state.ep_tail - state.ep_head)

    def _check_add_shapes(self, obs, action, reward, next_obs, terminated, truncated) -> None:
        e, o, a = self.num_envs, self.obs_size, self.action_size
        expected = {"obs": (obs, (e, o)), "action": (action, (e, a)), "reward": (reward, (e,)),
                    "next_obs": (next_obs, (e, o)), "terminated": (terminated, (e,)),
                    "truncated": (truncated, (e,))}  # fmt: skip
        for name, (x, shape) in expected.items():
            if jnp.shape(x) != shape:
                raise ValueError(f"Buffer.add: {name} has shape {jnp.shape(x)}, expected {shape}")


def _live_max(ep_return: jax.Array, ep_head: jax.Array, ep_tail: jax.Array) -> jax.Array:
    """[] max of ep_return [E, M] over each env's live slots [head, tail) (mod M); -inf if none."""
    m = ep_return.shape[1]
    rel = (jnp.arange(m)[None, :] - ep_head[:, None]) % m
    live = rel < (ep_tail - ep_head)[:, None]
    return jnp.max(jnp.where(live, ep_return, -jnp.inf))


def make_buffer(
    capacity: int, num_envs: int, obs_size: int, action_size: int, horizon: int,
    batch_size: int, *, discount: float = 1.0, rmax_mode: str = "in_buffer",
    sampling: str = "episode",
) -> Buffer:  # fmt: skip
    """Builds a `Buffer`; validates the static configuration.

    Args:
      capacity: entries in all (one per transition plus one per episode); each env gets
        capacity // num_envs.
      num_envs: E, envs adding one transition each per `add`.
      obs_size, action_size: O and A.
      horizon: H; samples hold H + 1 observations. Episodes of <= H + 1 entries are dropped.
      batch_size: B windows per `sample`.
      discount: 1.0 records the undiscounted return; in (0, 1) the discounted one.
      rmax_mode: "in_buffer" (max R over live episodes) or "all_time" (max over all recorded).
      sampling: "episode" (TD-MPC2's SliceSampler) or "transition" (FastTD3's), `SAMPLINGS`.
    """
    sizes = {"num_envs": num_envs, "obs_size": obs_size, "action_size": action_size,
             "horizon": horizon, "batch_size": batch_size}  # fmt: skip
    for name, value in sizes.items():
        if not isinstance(value, numbers.Integral) or value < 1:
            raise ValueError(f"make_buffer: {name} must be an int >= 1, got {value!r}")
    min_capacity = num_envs * (horizon + 2)
    if not isinstance(capacity, numbers.Integral) or capacity < min_capacity:
        raise ValueError(
            f"make_buffer: capacity must be an int >= num_envs * (horizon + 2) = {min_capacity} "
            f"so one sampleable episode fits per env, got {capacity!r}"
        )
    if capacity // num_envs >= 2**31 - 2**20:
        raise ValueError(f"make_buffer: capacity // num_envs must be < 2**31, got {capacity!r}")
    if not 0.0 < discount <= 1.0:
        raise ValueError(f"make_buffer: discount must be in (0, 1], got {discount!r}")
    if rmax_mode not in RMAX_MODES:
        raise ValueError(f"make_buffer: rmax_mode must be one of {RMAX_MODES}, got {rmax_mode!r}")
    if sampling not in SAMPLINGS:
        raise ValueError(f"make_buffer: sampling={sampling!r} is invalid; allowed: "
                         f"{', '.join(SAMPLINGS)}")  # fmt: skip
    return Buffer(capacity, num_envs, obs_size, action_size, horizon, batch_size,
                  float(discount), rmax_mode, sampling)  # fmt: skip
