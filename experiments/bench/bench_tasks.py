"""Compile time and CPU throughput of every locomotion task, next to the bare robot.

For each task: the contact slots MJX allocates per env, the time to compile `VecEnv.reset` and
`VecEnv.step` (E envs, jitted, the model as a jit argument; wall and process CPU seconds, the
latter less sensitive to other jobs on the machine), then control steps/s (E x calls / s) of the
compiled step under uniform random actions, with auto-resets. The reference row "bare" is the
robot on flat ground with a zero reward, so `ratio` is the task's cost of scene contacts and
reward.

    .venv/bin/python -m experiments.bench.bench_tasks [--variant h1hand] [--num-envs 64]
        [--calls 20] [--tasks walk,pole]

Compiles are not cached (a cached compile would time a disk read); timings on a shared 2-core
machine vary by +-30%, so compare the ratios of one run.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs.base import VecEnv
from sirl_jax.envs.humanoid import HumanoidEnv, Task

try:  # the contact slots MJX allocates per env (its collision driver's own count)
    from mujoco.mjx._src.collision_driver import make_condim as mjx_contact_dims
except ImportError:  # pragma: no cover - private MJX module moved

    def mjx_contact_dims(model):
        return []


class BareTask(Task):
    """No scene, zero reward, never terminates: the physics-only reference."""

    name = "bare"

    def evaluate(self, robot, data, task_state):
        return jnp.zeros(()), jnp.zeros((), bool), task_state, {}


def bench(env: HumanoidEnv, num_envs: int, calls: int, seed: int = 0) -> dict[str, float]:
    """Compile seconds of reset and step, and control steps/s of the step, for one env."""

    def reset(mx, key):
        return VecEnv(env.with_model(mx), num_envs).reset(key)

    def step(mx, state, action):
        return VecEnv(env.with_model(mx), num_envs).step(state, action)

    key = jax.random.PRNGKey(seed)
    c0, t0 = time.process_time(), time.perf_counter()
    reset_c = jax.jit(reset).lower(env.mx, key).compile()
    c1, t1 = time.process_time(), time.perf_counter()
    state = reset_c(env.mx, key)
    actions = jax.random.uniform(key, (calls, num_envs, env.action_size), minval=-1.0, maxval=1.0)
    c2, t2 = time.process_time(), time.perf_counter()
    step_c = jax.jit(step, donate_argnums=1).lower(env.mx, state, actions[0]).compile()
    c3, t3 = time.process_time(), time.perf_counter()
    state = step_c(env.mx, state, actions[0])  # warm-up
    jax.block_until_ready(state.obs)
    t4 = time.perf_counter()
    for i in range(calls):
        state = step_c(env.mx, state, actions[i])
    jax.block_until_ready(state.obs)
    t5 = time.perf_counter()
    return {
        "reset_compile_s": t1 - t0,
        "step_compile_s": t3 - t2,
        "compile_cpu_s": (c1 - c0) + (c3 - c2),
        "steps_per_s": num_envs * calls / (t5 - t4),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="h1hand", choices=tasks.VARIANTS)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--calls", type=int, default=20)
    parser.add_argument("--tasks", default="", help="comma-separated task names (default: all)")
    args = parser.parse_args()
    names = [r.name for r in tasks.LOCOMOTION]
    chosen = [n for n in args.tasks.split(",") if n] or names
    unknown = sorted(set(chosen) - set(names))
    if unknown:
        raise SystemExit(f"unknown tasks {unknown}; allowed: {names}")
    rows = {r.name: r for r in tasks.LOCOMOTION}
    print(f"variant {args.variant}, E = {args.num_envs}, {args.calls} timed calls, "
          f"backend {jax.default_backend()}")
    header = (f"{'task':<16}{'contacts':>9}{'reset compile s':>16}{'step compile s':>16}"
              f"{'compile CPU s':>14}{'steps/s':>9}{'ratio':>7}")
    print(header)
    print("-" * len(header))

    def report(name: str, env: HumanoidEnv, out: dict, ref_steps: float) -> None:
        contacts = len(mjx_contact_dims(env.mj_model))
        print(f"{name:<16}{contacts:>9}{out['reset_compile_s']:>16.1f}"
              f"{out['step_compile_s']:>16.1f}{out['compile_cpu_s']:>14.1f}"
              f"{out['steps_per_s']:>9.0f}{out['steps_per_s'] / ref_steps:>7.2f}", flush=True)

    bare = HumanoidEnv(BareTask(), args.variant)
    ref = bench(bare, args.num_envs, args.calls)
    report("bare", bare, ref, ref["steps_per_s"])
    for name in chosen:
        row = rows[name]
        env = HumanoidEnv(row.task(), args.variant, success_bar=row.success_bar)
        report(name, env, bench(env, args.num_envs, args.calls), ref["steps_per_s"])


if __name__ == "__main__":
    main()
