"""Replay sampling laws: TD-MPC2's episode-uniform slices and FastTD3's uniform transitions."""

from __future__ import annotations

import collections

import jax
import numpy as np
import pytest
from scipy import stats
from test_buffer import (
    CHUNK,
    TRACES,
    E,
    H,
    RefBuffer,
    chunks,
    make_fns,
    make_stream,
    run_against_reference,  # fmt: skip
)


@pytest.fixture(scope="module")
def fns_episode():
    return make_fns()


@pytest.fixture(scope="module")
def fns_transition():
    return make_fns(sampling="transition")


@pytest.mark.timeout(180)
def test_transition_sampling_draws_valid_windows(fns_transition):
    """FastTD3's sampling: every window within one live recorded episode, as the reference."""
    run_against_reference(fns_transition, 1.0, "in_buffer", seed=0)
    assert TRACES.count("transition") == 1, "run_chunk retraced"


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sampling", ["episode", "transition"])
def test_episode_or_transition_uniform_sampling(fns_episode, fns_transition, sampling):
    """episode: episodes drawn uniformly whatever their length, starts uniform within one;
    transition: every window of every live episode equally likely (an episode in proportion
    to its T + 1 - H windows)."""
    buf, run_chunk, sample = fns_episode if sampling == "episode" else fns_transition
    cycles = {0: [4, 12], 1: [5, 8], 2: [3, 20]}
    counters = collections.Counter()

    def cycle_length(e, rng):
        counters[e] += 1
        return cycles[e][counters[e] % 2]

    num_steps = 60
    data, episodes = make_stream(num_steps, cycle_length, seed=2)
    ref = RefBuffer(episodes)
    state = buf.init()
    for _, chunk in chunks(data, num_steps):
        state = run_chunk(state, chunk)
        for s in range(CHUNK):
            for e in range(E):
                ref.add(e, int(chunk["obs"][s, e, 1]), int(chunk["obs"][s, e, 2]), 0.0)
    live = sorted(ref.live())
    lengths = {episodes[ep].length for ep in live}
    assert len(live) >= 5 and max(lengths) >= 3 * min(lengths)
    by_episode, by_start = collections.Counter(), collections.Counter()
    for key in jax.random.split(jax.random.PRNGKey(3), 100):
        obs = np.asarray(sample(state, key).obs[0])
        by_episode.update(obs[:, 1].astype(int).tolist())
        by_start.update(zip(*obs[:, 1:3].astype(int).T.tolist(), strict=True))
    assert set(by_episode) == set(live)
    counts = np.array([by_episode[ep] for ep in live])
    windows = np.array([episodes[ep].length + 1 - H for ep in live], float)
    share = np.full(len(live), 1 / len(live)) if sampling == "episode" else windows / windows.sum()
    expected = counts.sum() * share
    chi2 = np.sum((counts - expected) ** 2 / expected)
    assert chi2 < stats.chi2.ppf(0.999, len(live) - 1), (counts, expected, chi2)
    # The two laws differ measurably here: each one's counts are far from the other's.
    uniform = np.full(len(live), 1 / len(live))
    wrong = counts.sum() * (windows / windows.sum() if sampling == "episode" else uniform)
    assert np.sum((counts - wrong) ** 2 / wrong) > stats.chi2.ppf(0.999999, len(live) - 1)
    # Pooled over episodes: each of the T + 1 - H starts equally likely.
    chi2, dof = 0.0, 0
    for ep in live:
        starts = np.array([by_start[(ep, k)] for k in range(episodes[ep].length + 1 - H)])
        assert starts.sum() == by_episode[ep]
        chi2 += np.sum((starts - starts.mean()) ** 2 / starts.mean())
        dof += len(starts) - 1
    assert chi2 < stats.chi2.ppf(0.999, dof), (chi2, dof)
