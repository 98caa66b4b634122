"""Compile time and CPU throughput of every locomotion task, next to the bare robot.

For each task: the contact slots MJX allocates per env, the time to compile `VecEnv.reset` and
`VecEnv.step` (E envs, jitted, the model as a jit argument; wall and process CPU seconds, the
latter less sensitive to other jobs on the machine), then control steps/s (E x calls / s) of the
compiled step under uniform random actions, with auto-resets. The reference row "bare" is the
robot on flat ground with a zero reward, so `ratio` is the task's cost of scene contacts and
reward. The ratio is measured side by side: `--rounds` alternating blocks of `--calls` steps of
the task and of the (already compiled) bare robot, ratio = median task rate / median bare rate,
so a change of machine load during the run moves both.

    .venv/bin/python -m experiments.bench.bench_tasks [--variant h1hand] [--num-envs 64]
        [--calls 10] [--rounds 3] [--tasks walk,pole]

Compiles are not cached (a cached compile would time a disk read).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs.base import EnvState, VecEnv
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


class Stepper:
    """One env's compiled `VecEnv.step` (state donated), its state and a block of actions."""

    def __init__(self, env: HumanoidEnv, num_envs: int, calls: int, seed: int = 0):
        """Compiles reset and step; `self.compile` holds wall and CPU seconds."""

        def reset(mx, key):
            return VecEnv(env.with_model(mx), num_envs).reset(key)

        def step(mx, state, action):
            return VecEnv(env.with_model(mx), num_envs).step(state, action)

        self.env, self.num_envs = env, num_envs
        key = jax.random.PRNGKey(seed)
        c0, t0 = time.process_time(), time.perf_counter()
        reset_c = jax.jit(reset).lower(env.mx, key).compile()
        c1, t1 = time.process_time(), time.perf_counter()
        self.state: EnvState = reset_c(env.mx, key)
        self.actions = jax.random.uniform(
            key, (calls, num_envs, env.action_size), minval=-1.0, maxval=1.0
        )  # [calls, E, A]
        c2, t2 = time.process_time(), time.perf_counter()
        self.step: Callable = (
            jax.jit(step, donate_argnums=1).lower(env.mx, self.state, self.actions[0]).compile()
        )
        c3, t3 = time.process_time(), time.perf_counter()
        self.compile = {
            "reset_compile_s": t1 - t0,
            "step_compile_s": t3 - t2,
            "compile_cpu_s": (c1 - c0) + (c3 - c2),
        }
        self.rate()  # warm-up

    def rate(self) -> float:
        """Control steps/s (E x calls / wall s) of one block of `calls` steps."""
        jax.block_until_ready(self.state.obs)
        t0 = time.perf_counter()
        for action in self.actions:
            self.state = self.step(self.env.mx, self.state, action)
        jax.block_until_ready(self.state.obs)
        return self.num_envs * len(self.actions) / (time.perf_counter() - t0)


def side_by_side(task: Stepper, bare: Stepper, rounds: int) -> tuple[float, float]:
    """(median task steps/s, median task / bare ratio) over `rounds` alternating blocks."""
    task_rates, bare_rates = [], []
    for _ in range(rounds):
        task_rates.append(task.rate())
        bare_rates.append(bare.rate())
    task_rate = statistics.median(task_rates)
    return task_rate, task_rate / statistics.median(bare_rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="h1hand", choices=tasks.VARIANTS)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--calls", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--tasks", default="", help="comma-separated task names (default: all)")
    args = parser.parse_args()
    if args.calls < 1 or args.rounds < 1:
        raise SystemExit(f"--calls and --rounds must be >= 1, got {args.calls}, {args.rounds}")
    names = [r.name for r in tasks.LOCOMOTION]
    chosen = [n for n in args.tasks.split(",") if n] or names
    unknown = sorted(set(chosen) - set(names))
    if unknown:
        raise SystemExit(f"unknown tasks {unknown}; allowed: {names}")
    rows = {r.name: r for r in tasks.LOCOMOTION}
    print(f"variant {args.variant}, E = {args.num_envs}, {args.rounds} x {args.calls} timed "
          f"calls, backend {jax.default_backend()}")
    header = (f"{'task':<16}{'contacts':>9}{'reset compile s':>16}{'step compile s':>16}"
              f"{'compile CPU s':>14}{'steps/s':>9}{'ratio':>7}")
    print(header)
    print("-" * len(header))

    def report(name: str, env: HumanoidEnv, compile_s: dict, rate: float, ratio: float) -> None:
        contacts = len(mjx_contact_dims(env.mj_model))
        print(f"{name:<16}{contacts:>9}{compile_s['reset_compile_s']:>16.1f}"
              f"{compile_s['step_compile_s']:>16.1f}{compile_s['compile_cpu_s']:>14.1f}"
              f"{rate:>9.0f}{ratio:>7.2f}", flush=True)

    bare = Stepper(HumanoidEnv(BareTask(), args.variant), args.num_envs, args.calls)
    rate = statistics.median(bare.rate() for _ in range(args.rounds))
    report("bare", bare.env, bare.compile, rate, 1.0)
    for name in chosen:
        row = rows[name]
        env = HumanoidEnv(row.task(), args.variant, success_bar=row.success_bar)
        stepper = Stepper(env, args.num_envs, args.calls)
        report(name, env, stepper.compile, *side_by_side(stepper, bare, args.rounds))
        del stepper


if __name__ == "__main__":
    main()
