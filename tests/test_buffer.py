"""Replay buffer: checked against a tag-based Python model of per-env rings.

Every observation encodes (env, episode id, step index), actions and rewards are functions of
(episode, step), so each sampled window can be checked against what was added. The model
tracks which (episode, entry) tag sits in each ring slot and calls an episode live iff it ended
with more than H + 1 entries and all its tags are still in the ring.
"""

from __future__ import annotations

import collections
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.buffer import make_buffer
from sirl_jax.run.buffer_memory import BufferTooLargeError, check_buffer_fits


def buffer_nbytes(capacity, num_envs, obs_size, action_size, horizon) -> int:
    return make_buffer(capacity, num_envs, obs_size, action_size, horizon, 1).nbytes

E, O, A, H, B = 3, 4, 2, 3, 64
RING = 30  # entries per env
CHUNK = 20  # env steps per jitted scan
F32 = np.float32


def encode_obs(env, ep, k):
    return np.array([env, ep, k, ep * 1000 + k], F32)


def encode_action(ep, k):
    return np.array([ep + 0.25, k + 0.5], F32)


@dataclasses.dataclass
class Episode:
    env: int
    length: int  # transitions T
    terminated: bool
    rewards: np.ndarray


def make_stream(num_steps, pick_length, seed):
    """Arrays for `add` ([N, E, ...]) and the episodes they contain, keyed by episode id."""
    rng = np.random.default_rng(seed)
    data = {
        "obs": np.zeros((num_steps, E, O), F32),
        "action": np.zeros((num_steps, E, A), F32),
        "reward": np.zeros((num_steps, E), F32),
        "next_obs": np.zeros((num_steps, E, O), F32),
        "terminated": np.zeros((num_steps, E), bool),
        "truncated": np.zeros((num_steps, E), bool),
    }
    episodes, current, step = {}, [None] * E, [0] * E
    for t in range(num_steps):
        for e in range(E):
            if current[e] is None:
                current[e], step[e] = len(episodes), 0
                length = pick_length(e, rng)
                rewards = rng.uniform(-1.0, 2.0, length).astype(F32)
                episodes[current[e]] = Episode(e, length, bool(rng.random() < 0.5), rewards)
            ep, k = current[e], step[e]
            info = episodes[ep]
            done = k + 1 == info.length
            data["obs"][t, e] = encode_obs(e, ep, k)
            data["next_obs"][t, e] = encode_obs(e, ep, k + 1)
            data["action"][t, e] = encode_action(ep, k)
            data["reward"][t, e] = info.rewards[k]
            data["terminated"][t, e] = done and info.terminated
            data["truncated"][t, e] = done and not info.terminated
            step[e] += 1
            if done:
                current[e] = None
    return data, episodes


class RefBuffer:
    """Per-env rings of (episode, entry) tags; the independent model of the buffer."""

    def __init__(self, episodes, discount=1.0):
        self.episodes, self.discount = episodes, discount
        self.tags = [[None] * RING for _ in range(E)]
        self.ptr = [0] * E
        self.running = [None] * E  # (episode, start ring index, return, discount^k)
        self.returns = {}  # recorded episodes (> H + 1 entries)
        self.ever_live = set()
        self.short = self.evicted = 0

    def _write(self, e, tag):
        self.tags[e][self.ptr[e]] = tag
        self.ptr[e] = (self.ptr[e] + 1) % RING

    def add(self, e, ep, k, reward):
        live_before = self.live()
        if self.running[e] is None:
            self.running[e] = (ep, self.ptr[e], F32(0.0), F32(1.0))
            self._write(e, (ep, 0))
        self._write(e, (ep, k + 1))
        _, start, ret, disc = self.running[e]
        ret, disc = F32(ret + disc * reward), F32(disc * F32(self.discount))
        self.running[e] = (ep, start, ret, disc)
        self.evicted += len(live_before - self.live())
        if k + 1 == self.episodes[ep].length:
            self.running[e] = None
            if k + 2 <= H + 1:
                self.ptr[e] = start  # dropped: its slots are reused
                self.short += 1
            else:
                self.returns[ep] = ret
                if ep in self.live():
                    self.ever_live.add(ep)

    def live(self):
        present = {tag for ring in self.tags for tag in ring if tag is not None}
        return {
            ep
            for ep in self.returns
            if all((ep, i) in present for i in range(self.episodes[ep].length + 1))
        }

    def r_max(self, mode):
        eps = self.live() if mode == "in_buffer" else self.ever_live
        return max((self.returns[ep] for ep in eps), default=-np.inf)


TRACES = []


def make_fns(discount=1.0, rmax_mode="in_buffer", sampling="episode"):
    buf = make_buffer(E * RING, E, O, A, H, B, discount=discount, rmax_mode=rmax_mode,
                      sampling=sampling)  # fmt: skip

    def run_chunk(state, data):
        TRACES.append(rmax_mode if sampling == "episode" else sampling)

        def body(s, x):
            return buf.add(s, *x), None

        xs = tuple(data[k] for k in ("obs", "action", "reward", "next_obs"))
        xs += (data["terminated"], data["truncated"])
        return jax.lax.scan(body, state, xs)[0]

    return buf, jax.jit(run_chunk), jax.jit(buf.sample)


@pytest.fixture(scope="module")
def fns_in_buffer():
    return make_fns()


@pytest.fixture(scope="module")
def fns_all_time_discounted():
    return make_fns(discount=0.9, rmax_mode="all_time")



def random_length(e, rng):
    # Short drops (<= 3 transitions), long ones, and one longer than the ring (31+ entries).
    return int(rng.choice([1, 2, 3, 4, 5, 8, 12, 17, 24, 31]))


def chunks(data, num_steps):
    for t in range(0, num_steps, CHUNK):
        yield t, {k: v[t : t + CHUNK] for k, v in data.items()}


def check_batch(batch, ref, episodes, mode):
    obs = np.asarray(batch.obs)
    assert obs.shape == (H + 1, B, O) and batch.action.shape == (H, B, A)
    assert batch.reward.shape == (H, B) and batch.terminated.shape == (H, B)
    assert not np.isnan(obs).any() and not np.isnan(np.asarray(batch.action)).any()
    live = ref.live()
    for b in range(B):
        env, ep, k0 = (int(v) for v in obs[0, b, :3])
        assert ep in live, f"window from episode {ep} that is not live"
        info = episodes[ep]
        assert info.env == env
        for t in range(H + 1):
            np.testing.assert_array_equal(obs[t, b], encode_obs(env, ep, k0 + t))
        for t in range(H):
            np.testing.assert_array_equal(batch.action[t, b], encode_action(ep, k0 + t))
            assert batch.reward[t, b] == info.rewards[k0 + t]
            last = k0 + t + 1 == info.length
            assert batch.terminated[t, b] == float(last and info.terminated)
        np.testing.assert_allclose(batch.episode_return[b], ref.returns[ep], rtol=1e-6)


def run_against_reference(fns, discount, mode, seed):
    buf, run_chunk, sample = fns
    num_steps = 160  # about 6 laps of each 30-entry ring
    data, episodes = make_stream(num_steps, random_length, seed)
    ref = RefBuffer(episodes, discount)
    state, key = buf.init(), jax.random.PRNGKey(seed)
    assert not buf.can_sample(state) and buf.r_max(state) == -np.inf
    seen = collections.Counter()
    r_max_history = []
    for _, chunk in chunks(data, num_steps):
        state = run_chunk(state, chunk)
        for s in range(CHUNK):
            for e in range(E):
                ep, k = int(chunk["obs"][s, e, 1]), int(chunk["obs"][s, e, 2])
                ref.add(e, ep, k, chunk["reward"][s, e])
        assert int(buf.num_episodes(state)) == len(ref.live())
        assert bool(buf.can_sample(state)) == bool(ref.live())
        np.testing.assert_allclose(buf.r_max(state), ref.r_max(mode), rtol=1e-6)
        np.testing.assert_allclose(state.r_max_all_time, ref.r_max("all_time"), rtol=1e-6)
        r_max_history.append((ref.r_max("in_buffer"), ref.r_max("all_time")))
        if ref.live():
            for _ in range(2):
                key, key_sample = jax.random.split(key)
                batch = sample(state, key_sample)
                check_batch(batch, ref, episodes, mode)
                seen.update(np.asarray(batch.terminated).ravel().tolist())
    # The stream must exercise what the checks are about.
    assert ref.evicted > 5 and ref.short > 5
    assert any(e.length + 1 > RING for e in episodes.values())
    assert seen[1.0] > 0 and seen[0.0] > 0
    return r_max_history


@pytest.mark.timeout(180)
def test_matches_reference_in_buffer(fns_in_buffer):
    """Wrap-around, boundaries, running/short/overlong episodes, returns, R_max in_buffer."""
    history = run_against_reference(fns_in_buffer, 1.0, "in_buffer", seed=0)
    in_buffer = [h[0] for h in history]
    assert any(b < a for a, b in zip(in_buffer, in_buffer[1:], strict=False)), "R_max never dropped"
    assert any(a < b for a, b in history), "eviction never lowered in_buffer below all_time"
    assert TRACES.count("in_buffer") == 1, "run_chunk retraced"


@pytest.mark.timeout(180)
def test_matches_reference_all_time_discounted(fns_all_time_discounted):
    """R_max all_time keeps the best episode after eviction; discounted returns."""
    history = run_against_reference(fns_all_time_discounted, 0.9, "all_time", seed=1)
    assert any(a < b for a, b in history)


@pytest.mark.timeout(180)
def test_vmap_over_seeds_matches_single(fns_in_buffer):
    buf, run_chunk, sample = fns_in_buffer
    streams = [make_stream(CHUNK, random_length, seed)[0] for seed in (4, 5)]
    stacked = {k: np.stack([s[k] for s in streams]) for k in streams[0]}
    keys = jax.random.split(jax.random.PRNGKey(6), 2)
    states = jax.jit(jax.vmap(lambda _: buf.init()))(jnp.arange(2))
    states = jax.jit(jax.vmap(run_chunk))(states, stacked)
    batches = jax.jit(jax.vmap(buf.sample))(states, keys)
    for i in range(2):
        single = run_chunk(buf.init(), streams[i])
        assert bool(buf.can_sample(single))
        jax.tree.map(
            lambda v, s, i=i: np.testing.assert_array_equal(v[i], s),
            (states, batches),
            (single, sample(single, keys[i])),
        )


def test_memory_estimate_h1hand():
    raw = (151 + 61 + 1) * 4 + 2  # float32 obs, action, reward + two 1-byte flags
    for num_envs in (1, 32):
        nbytes = buffer_nbytes(3_000_000, num_envs, 151, 61, 3)
        assert 2.5e9 < nbytes < 2.7e9
        assert nbytes >= 3_000_000 * raw
        assert nbytes / 3_000_000 <= 1.1 * raw
    buf = make_buffer(3_000_000, 32, 151, 61, 3, 256)
    assert buf.nbytes == buffer_nbytes(3_000_000, 32, 151, 61, 3)
    assert "3,000,000" in buf.describe() and "GB" in buf.describe()


def test_check_buffer_fits():
    check_buffer_fits(1 << 20)
    with pytest.raises(BufferTooLargeError, match="--buffer-size"):
        check_buffer_fits(buffer_nbytes(10**9, 1, 151, 61, 3) * 10**3)


@pytest.mark.parametrize(
    "kwargs, bad",
    [
        ({"capacity": 14}, "capacity"),
        ({"horizon": 0}, "horizon"),
        ({"num_envs": 0}, "num_envs"),
        ({"batch_size": 0}, "batch_size"),
        ({"discount": 0.0}, "discount"),
        ({"rmax_mode": "best"}, "rmax_mode"),
    ],
)
def test_bad_arguments_raise(kwargs, bad):
    args = {"capacity": 90, "num_envs": 3, "obs_size": O, "action_size": A, "horizon": H}
    args.update(batch_size=B)
    args.update(kwargs)
    with pytest.raises(ValueError, match=bad):
        make_buffer(**args)


def test_add_rejects_bad_shapes():
    buf = make_buffer(E * RING, E, O, A, H, B)
    good = (np.zeros((E, O)), np.zeros((E, A)), np.zeros(E), np.zeros((E, O)))
    flags = (np.zeros(E, bool), np.zeros(E, bool))
    with pytest.raises(ValueError, match="next_obs"):
        buf.add(buf.init(), *good[:3], np.zeros((E, O + 1)), *flags)
    with pytest.raises(ValueError, match="action"):
        buf.add(buf.init(), good[0], np.zeros((E + 1, A)), *good[2:], *flags)
