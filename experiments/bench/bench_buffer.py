"""Replay buffer add/sample time at h1hand sizes (O=151, A=61, H=3, B=256).

    .venv/bin/python -m experiments.bench.bench_buffer [--capacity 3000000] [--envs 1 32]

Times a jitted, donated `lax.scan` of `--steps` adds (one transition per env each) and of
`--steps` samples, after warm-up, and prints the median microseconds per call. Both R_max modes are
timed side by side: "in_buffer" recomputes a masked max over the [E, M] episode table each add.
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import jax.numpy as jnp

from sirl_jax.buffer import make_buffer
from sirl_jax.run.buffer_memory import check_buffer_fits
from sirl_jax.run.compile_cache import enable_compilation_cache

OBS, ACT, HORIZON, BATCH = 151, 61, 3, 256


def _median_time(fn, args_list) -> float:
    """Median seconds of fn(*args) over args_list, after one warm-up call (the CPU is shared)."""
    jax.block_until_ready(fn(*args_list[0]))
    times = []
    for args in args_list[1:]:
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench(
    capacity: int, num_envs: int, rmax_mode: str, steps: int, episode_length: int, repeats: int
):
    buf = make_buffer(capacity, num_envs, OBS, ACT, HORIZON, BATCH, rmax_mode=rmax_mode)
    check_buffer_fits(buf.nbytes)

    def add_chunk(state, t0):
        def body(s, t):
            obs = jnp.full((num_envs, OBS), t, jnp.float32)
            action = jnp.zeros((num_envs, ACT), jnp.float32)
            reward = jnp.ones((num_envs,), jnp.float32)
            done = jnp.full((num_envs,), (t + 1) % episode_length == 0)
            return buf.add(s, obs, action, reward, obs + 1, done, jnp.zeros_like(done)), None

        return jax.lax.scan(body, state, t0 + jnp.arange(steps))[0]

    def sample_chunk(state, key):
        def body(_, k):
            # Reduce every field so XLA cannot drop any part of the gather.
            return None, sum(jnp.sum(x) for x in jax.tree.leaves(buf.sample(state, k)))

        return jax.lax.scan(body, None, jax.random.split(key, steps))[1]

    add_jit = jax.jit(add_chunk, donate_argnums=0)
    state = buf.init()
    t0 = 0
    for _ in range(max(1, 2 * episode_length // steps)):  # a few finished episodes first
        state = add_jit(state, t0)
        t0 += steps
    add_times = []
    for _ in range(repeats):
        start = time.perf_counter()
        state = jax.block_until_ready(add_jit(state, t0))
        add_times.append(time.perf_counter() - start)
        t0 += steps
    assert bool(buf.can_sample(state))
    keys = [(state, k) for k in jax.random.split(jax.random.PRNGKey(0), repeats + 1)]
    sample_s = _median_time(jax.jit(sample_chunk), keys)
    return buf, statistics.median(add_times) / steps, sample_s / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--capacity", type=int, default=1_000_000)
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 32])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--episode-length", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    enable_compilation_cache()
    print(f"device: {jax.devices()[0]}  capacity {args.capacity:,}  O={OBS} A={ACT} B={BATCH}")
    print(f"{'envs':>5} {'rmax_mode':>10} {'GB':>7} {'add us/step':>12} {'sample us':>10}")
    for num_envs in args.envs:
        for mode in ("in_buffer", "all_time"):
            buf, add_s, sample_s = bench(
                args.capacity, num_envs, mode, args.steps, args.episode_length, args.repeats
            )
            print(
                f"{num_envs:>5} {mode:>10} {buf.nbytes / 1e9:>7.3f} "
                f"{add_s * 1e6:>12.1f} {sample_s * 1e6:>10.1f}"
            )


if __name__ == "__main__":
    main()
