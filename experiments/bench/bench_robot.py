"""Throughput of the H1 + Shadow hands model: MJX on CPU vs MuJoCo C, measured side by side.

One control step = 10 physics steps (50 Hz). Columns:
  MJX per-call: `jit(vmap(control_step))` called once per control step from Python.
  MJX scan:     `jit` of a `lax.scan` over CHUNK control steps of `vmap(control_step)`.
  impl:         the MJX backend of those two columns, "jax" or "warp" (MJX-Warp on its CPU
                device, buffers sized by `sirl_jax.envs.physics`; needs warp-lang).
  MuJoCo C:     one thread (`mj_step` loop), and `mujoco.rollout` on 2 threads with E envs.
Also: compile time of one control step (E=1) and bytes of one env's `mjx.Data`.
Actions are small smooth perturbations of the keyframe-holding action (the robot stands, so
contacts stay realistic for locomotion).

Run: .venv/bin/python -m experiments.bench.bench_robot [--envs 1 16 64 256] [--contacts locomotion]
     .venv/bin/python -m experiments.bench.bench_robot --envs 64 --impls jax warp --skip-compile
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx, rollout

from sirl_jax.envs import h1
from sirl_jax.envs.control_step import make_control_step
from sirl_jax.envs.physics import Physics, Simulator, warp_unavailable
from sirl_jax.run.compile_cache import enable_compilation_cache

CHUNK = 20  # control steps per jitted scan
_EULERDAMP = int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)


def _actions(robot: h1.Robot, n_steps: int, n_envs: int) -> np.ndarray:
    """[T, E, A] smooth small actions around the keyframe-holding action."""
    t = np.arange(n_steps)[:, None, None] * h1.CONTROL_DT
    phase = np.random.default_rng(0).uniform(0, 2 * np.pi, (1, n_envs, robot.nu))
    a = robot.keyframe_action[None, None] + 0.05 * np.sin(2 * np.pi * t + phase)
    return np.clip(a, -1, 1).astype(np.float32)


def _timed(fn, repeats: int) -> float:
    """Median seconds of fn() over repeats (fn must block)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def bench_mjx(
    model, robot, n_envs: int, mode: str, repeats: int, impl: str = "jax"
) -> tuple[float, float]:
    """Returns (control steps/s summed over envs, first-call seconds incl. compile)."""
    sim = Simulator(model, Physics(impl, num_worlds=n_envs))
    mx = sim.mx
    d0 = h1.keyframe_data(model, mx, sim=sim)
    # vmap, not broadcast_to: MJX-Warp's data keeps its shared (contact pool) fields unbatched
    batch = jax.jit(jax.vmap(lambda _: d0))(jnp.zeros(n_envs))
    control_step = make_control_step()

    def one(mx, d, c):  # Warp's shared contact pool goes in and out around the step
        return sim.detach_pool(control_step(mx, sim.attach_pool(d), c))

    stepper = jax.vmap(one, in_axes=(None, 0, 0))
    ctrls = robot.action_to_ctrl(jnp.asarray(_actions(robot, CHUNK, n_envs)))
    if mode == "per-call":
        step = jax.jit(lambda d, c: stepper(mx, d, c))

        def run(d):
            for t in range(CHUNK):
                d = step(d, ctrls[t])
            return jax.block_until_ready(d)
    else:

        @jax.jit
        def chunk(d, ctrls):
            return jax.lax.scan(lambda d, c: (stepper(mx, d, c), None), d, ctrls)[0]

        def run(d):
            return jax.block_until_ready(chunk(d, ctrls))

    t0 = time.perf_counter()
    run(batch)
    first = time.perf_counter() - t0
    seconds = _timed(lambda: run(batch), repeats)
    return CHUNK * n_envs / seconds, first


def compile_seconds(model) -> float:
    """Seconds to lower and compile one jitted control step (E = 1) with the persistent cache
    pointed at a fresh directory (run `--compile-only` in a child process to get a cold number)."""
    mx = mjx.put_model(model)
    d0 = h1.keyframe_data(model, mx)
    stepper = make_control_step()
    step = jax.jit(lambda d, c: stepper(mx, d, c))
    t0 = time.perf_counter()
    step.lower(d0, d0.ctrl).compile()
    return time.perf_counter() - t0


def cold_compile_seconds(args: argparse.Namespace) -> float:
    """Runs `--compile-only` in a child process with an empty compilation cache."""
    with tempfile.TemporaryDirectory() as cache:
        cmd = [sys.executable, "-m", "experiments.bench.bench_robot", "--compile-only"]
        cmd += ["--variant", args.variant, "--contacts", args.contacts]
        cmd += ["--solver", args.solver] if args.solver else []
        env = dict(os.environ, SIRL_JAX_CACHE_DIR=cache, JAX_PLATFORMS="cpu")
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
        return float(out.strip().splitlines()[-1])


def bench_c_single(model, robot, n_steps: int = 500) -> float:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    ctrls = np.asarray(robot.action_to_ctrl(jnp.asarray(_actions(robot, n_steps, 1))))[:, 0]
    t0 = time.perf_counter()
    for c in ctrls:
        data.ctrl[:] = c
        mujoco.mj_step(model, data, nstep=h1.N_SUBSTEPS)
    return n_steps / (time.perf_counter() - t0)


def bench_c_rollout(model, robot, n_envs: int, n_steps: int = 100, threads: int = 2) -> float:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    init = np.repeat(state[None], n_envs, axis=0)
    ctrl = np.asarray(robot.action_to_ctrl(jnp.asarray(_actions(robot, n_steps, n_envs))))
    ctrl = np.repeat(ctrl.transpose(1, 0, 2), h1.N_SUBSTEPS, axis=1).astype(np.float64)
    datas = [mujoco.MjData(model) for _ in range(threads)]
    with rollout.Rollout(nthread=threads) as runner:
        runner.rollout(model, datas, init[:1], ctrl[:1, :10])  # warm the pool
        t0 = time.perf_counter()
        runner.rollout(model, datas, init, ctrl)
        return n_envs * n_steps / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", type=int, nargs="*", default=[1, 16, 64, 256])
    parser.add_argument("--modes", nargs="*", default=["per-call", "scan"])
    parser.add_argument("--impls", nargs="*", default=["jax"], choices=["jax", "warp"])
    parser.add_argument("--variant", default="h1hand", choices=sorted(h1.VARIANTS))
    parser.add_argument("--contacts", default="locomotion", choices=h1.CONTACT_PROFILES)
    parser.add_argument(
        "--solver", default=None, help="override: iterations,ls_iterations,eulerdamp"
    )
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-compile", action="store_true", help="skip the cold compile")
    parser.add_argument("--compile-only", action="store_true", help="print compile seconds, exit")
    args = parser.parse_args()
    enable_compilation_cache()
    model = h1.load_model(args.variant, args.contacts)
    if args.solver:
        it, ls, eulerdamp = (int(x) for x in args.solver.split(","))
        model.opt.iterations, model.opt.ls_iterations = it, ls
        flags = model.opt.disableflags
        model.opt.disableflags = flags & ~_EULERDAMP if eulerdamp else flags | _EULERDAMP
    if args.compile_only:
        print(f"{compile_seconds(model):.1f}")
        return
    robot = h1.Robot(model)
    mx = mjx.put_model(model)
    d0 = h1.keyframe_data(model, mx)
    nbytes = sum(x.nbytes for x in jax.tree.leaves(d0) if hasattr(x, "nbytes"))
    c1 = bench_c_single(model, robot)
    print(
        f"model {args.variant}/{args.contacts}: nq {model.nq} nv {model.nv} nu {model.nu}, "
        f"contact slots {d0._impl.contact.dist.shape[0]}, solver {model.opt.iterations}/"
        f"{model.opt.ls_iterations} eulerdamp "
        f"{'off' if model.opt.disableflags & _EULERDAMP else 'on'}, "
        f"mjx.Data {nbytes / 1024:.1f} KiB per env"
    )
    print(f"MuJoCo C, 1 thread: {c1:.0f} control steps/s")
    if not args.skip_compile:
        print(f"cold compile of one control step (E=1): {cold_compile_seconds(args):.0f} s")
    print(
        "\n| E | impl | MJX per-call (steps/s) | MJX scan (steps/s) | C rollout 2 threads | "
        "C 1 thread | MJX best / C 1 thread | first call (s) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for n_envs in args.envs:
        for impl in args.impls:
            if impl == "warp" and warp_unavailable():
                print(f"| {n_envs} | warp | {warp_unavailable()} |", flush=True)
                continue
            row, firsts = {}, []
            for mode in args.modes:
                rate, first = bench_mjx(model, robot, n_envs, mode, args.repeats, impl)
                row[mode] = rate
                firsts.append(f"{first:.0f}")
            roll = bench_c_rollout(model, robot, n_envs, n_steps=max(20, 1000 // n_envs))
            c1 = bench_c_single(model, robot)  # again, next to the MJX numbers of this row
            best = max(row.values())
            print(
                f"| {n_envs} | {impl} | {row.get('per-call', float('nan')):.0f} | "
                f"{row.get('scan', float('nan')):.0f} | {roll:.0f} | {c1:.0f} | "
                f"{best / c1:.2f} | {'/'.join(firsts)} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
