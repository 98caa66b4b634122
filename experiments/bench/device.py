"""The device benchmark: the GPU path's figures in one table, and the paper's runtime projected.

    python experiments/bench/device.py                  # on a GPU: about 8 min, compiles included
    python experiments/bench/device.py --quick          # CPU check (a test runs it): tiny sizes
    python experiments/bench/device.py --json out.json  # the table as JSON too
    python experiments/bench/device.py --rows agent env  # a second call: only these row groups

Runs without `make` from wheels on PYTHONPATH (the repository root included). Rows:
  env      h1hand-walk `VecEnv` control steps/s summed over E envs, a `lax.scan` of K steps,
           impl jax and warp, E in {1, 64, 1024, 8192} ("not installed" without warp-lang).
  matmul   the device's float32 matmul rate ([n, n] @ [n, n], default precision), TFLOP/s.
  agent    the 5M agent's plan (E = 1, 16) and update: ms per call, analytic GFLOP
           (experiments/bench/bench_agent.py), achieved TFLOP/s, and time / matmul time (the
           agent core's target: 1.5x).
  train    the fused `Train.step`, env steps/s per seed, 3 seeds vmapped: the paper's setting
           (E = 1, UTD 1) and a throughput setting (E = 16, UTD 1/16 per env), SIRL on and off.
  project  hours for 2M steps x 3 seeds on walk, reach and hurdle (both settings), beside the
           paper's V100 hours. Walk's fused step is measured; reach and hurdle replace its env
           share by their own env step at 3 worlds (the task scenes differ only in physics).
  fasttd3  the FastTD3 learner's fused `Train.step` at the `fasttd3-gpu` preset's sizes (1024
           envs, batch 32768, critic 1024 / actor 512, 2 critic updates per vectorised step),
           one seed, SIRL on: env steps/s, with critic updates/s in the note.
  sweep    R = 3, 24, 12, 6 runs of the paper setting in one program, a sirl.beta sweep (0, 1,
           ...; `sirl_jax.sweep`): env steps/s per run, the 2M-step device-hours per run beside
           the paper's 12.5 V100-hours per run, and the state's GiB per run at 2M replay.
Train rows use 25-step episodes so the seed phase ends within a chunk (the per-step cost is
that of 1000-step ones). Rows run in priority order (the paper's projection first, Warp last);
a row starts only within `--budget` seconds (default 360, so the last one and the table end
inside 8 minutes, compiles included); a row past it reads "n/a: ..." (rerun: the persistent
compilation cache keeps what compiled), and so does a row that failed ("n/a: error: ...").
`--quick` keeps every row but sizes it tiny (the pendulum for every task, the tiny agent, the
throughput setting at the paper setting's sizes, so its train rows reuse those compiles) and
compiles with XLA's backend optimisations off: its figures check the script, nothing else.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a file: make `experiments` and `sirl_jax` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import jax

from experiments.bench.device_parts import (
    PAPER_RUN_HOURS,
    QUICK_XLA_FLAGS,
    RUN_STEPS,
    SEEDS,
    Sizes,
    Table,
    _timed,
    agent_jobs,
    env_seconds,
    matmul_tflops,
    peak_bytes,
    run_bytes,
    train_seconds,
)
from sirl_jax.envs import load
from sirl_jax.envs.physics import warp_unavailable
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.reference import paper_hours

ROW_GROUPS = ("matmul", "paper", "agent", "env", "fasttd3", "throughput", "sweep", "warp")


def row_names(sizes: Sizes) -> list[str]:
    """Every row of the table, in print order."""
    task, envs = sizes.env_task, sizes.env_envs
    names = [f"env {task} impl={i} E={e}" for i in ("jax", "warp") for e in envs]
    names += ["matmul float32"]
    names += [f"agent plan E={e}" for e in sizes.plan_envs] + ["agent update"]
    for name, e, _ in sizes.settings:
        names += [f"train {name} S={SEEDS} E={e} sirl={s}" for s in ("on", "off")]
        names += [f"train {name} SIRL overhead"]
    for task, _ in sizes.tasks:
        for name, _, _ in sizes.settings:
            names += [f"project {task} {name} {arm}" for arm in ("TDMPBC", "TD-MPC2")]
    names += [f"fasttd3 S=1 E={sizes.fasttd3_envs}"]
    names += [f"sweep {k} R={r}" for r in sizes.sweep_runs for k in ("steps", "memory")]
    return names


class Bench:
    """Runs the rows in priority order under the time budget; a failing row reads
    "n/a: error: ..." and the others still run."""

    def __init__(self, sizes: Sizes, table: Table, budget: float):
        self.sizes, self.table, self.budget = sizes, table, budget
        self.start = time.perf_counter()
        self.per_step: dict[tuple[str, bool], float] = {}  # seconds per vectorised env step
        self.mm = math.nan

    def run(self, row: str, fn) -> None:
        """Fills `row` with fn() -> (value, unit, note), unless past the budget or failing."""
        if time.perf_counter() - self.start > self.budget:
            self.table.set(row, f"n/a: over the {self.budget:.0f} s budget (rerun: compiles "
                                "are cached)")  # fmt: skip
            return
        try:
            self.table.set(row, *fn())
        except Exception as e:  # one bad row must not lose the others
            first = (str(e).strip().splitlines() or [""])[0][:200]
            self.table.set(row, f"n/a: error: {type(e).__name__}: {first}")

    def env_step(self, task: str, worlds: int) -> float:
        s = self.sizes
        return env_seconds(task, "jax", worlds, s.env_chunk, s.repeats)[0]

    def matmul(self) -> None:
        def fn():
            self.mm = matmul_tflops(self.sizes.matmul_n, self.sizes.repeats)
            n = self.sizes.matmul_n
            return self.mm, "TFLOP/s", f"[{n}, {n}] @ [{n}, {n}], default precision"

        self.run("matmul float32", fn)

    def agent(self, obs: int, act: int) -> None:
        for row, call, flops in agent_jobs(self.sizes, obs, act):

            def fn(call=call, flops=flops):
                first, seconds, _ = _timed(call, self.sizes.repeats)
                mm_seconds = flops / (self.mm * 1e12)
                note = (f"{flops / 1e9:.3g} GFLOP, {flops / seconds / 1e12:.3g} TFLOP/s, "
                        f"{seconds / mm_seconds:.2f}x its matmul time (target 1.5x), "
                        f"first call {first:.0f} s")  # fmt: skip
                return seconds * 1e3, "ms/call", note

            self.run(row, fn)

    def env(self, impl: str, num_envs: int, warp: str | None) -> None:
        s = self.sizes
        row = f"env {s.env_task} impl={impl} E={num_envs}"
        if impl == "warp" and warp is not None:
            self.table.set(row, "not installed" if "not installed" in warp else f"n/a: {warp}")
            return

        def fn():
            seconds, first = env_seconds(s.env_task, impl, num_envs, s.env_chunk, s.repeats)
            return num_envs / seconds, "steps/s", f"control steps, first call {first:.0f} s"

        self.run(row, fn)

    def train(self, setting: tuple[str, int, float]) -> None:
        s, (name, e, utd) = self.sizes, setting
        for sirl in (True, False):

            def fn(sirl=sirl):
                seconds, first, bad = train_seconds(s, s.tasks[0][1], e, utd, sirl)
                self.per_step[name, sirl] = seconds / s.train_chunk
                note = (f"per seed ({SEEDS * e * s.train_chunk / seconds:.4g} over the seeds),"
                        f" first call {first:.0f} s")  # fmt: skip
                if bad:
                    raise FloatingPointError(f"{bad} physics blow-ups or non-finite losses")
                return e * s.train_chunk / seconds, "env steps/s", note

            self.run(f"train {name} S={SEEDS} E={e} sirl={'on' if sirl else 'off'}", fn)

        def overhead():
            ratio = self.per_step[name, True] / self.per_step[name, False]
            return ratio, "x", "step time with SIRL / without"

        self.run(f"train {name} SIRL overhead", overhead)

    def fasttd3(self) -> None:
        s, e = self.sizes, self.sizes.fasttd3_envs

        def fn():
            seconds, first, bad = train_seconds(s, s.tasks[0][1], e, 1.0, True, s.fasttd3, 1)
            if bad:
                raise FloatingPointError(f"{bad} physics blow-ups or non-finite losses")
            critic = s.train_chunk * s.fasttd3.fasttd3.num_updates / seconds
            note = (f"{s.caveat}{critic:.4g} critic updates/s (batch "
                    f"{s.fasttd3.fasttd3.batch_size}), first call {first:.0f} s")  # fmt: skip
            return e * s.train_chunk / seconds, "env steps/s", note

        self.run(f"fasttd3 S=1 E={e}", fn)

    def sweep(self) -> None:
        """R runs of the paper setting (E = 1, UTD 1, SIRL on) as one beta sweep: env steps/s
        per run with the 2M-step cost per run against the paper's; the state's GiB per run at
        the gpu preset's replay (2M transitions), and the device's peak so far."""
        s = self.sizes
        per_run = run_bytes(s, s.tiny)[0]
        for r in s.sweep_runs:

            def steps(r=r):
                seconds, first, bad = train_seconds(s, s.tasks[0][1], 1, 1.0, True, seeds=r,
                                                    sweep=True)  # fmt: skip
                if bad:
                    raise FloatingPointError(f"{bad} physics blow-ups or non-finite losses")
                rate = s.train_chunk / seconds
                gpu_h = RUN_STEPS / rate / 3600 / r
                ratio = PAPER_RUN_HOURS / gpu_h
                return rate, "env steps/s per run", (
                    f"{s.caveat}{rate * r:.4g} over the runs; 2M steps: {gpu_h:.3g} device-h per "
                    f"run, paper {PAPER_RUN_HOURS:.3g} V100-h per run ({ratio:.3g}x), first call "
                    f"{first:.0f} s")  # fmt: skip

            def memory(r=r):
                peak = peak_bytes()
                note = f"peak so far {peak / 2**30:.3g} GiB" if peak else "no device peak here"
                where = "the smoke preset's" if s.tiny else "2M-transition"
                return per_run / 2**30, "GiB per run", f"{s.caveat}state at {where} replay; {note}"

            self.run(f"sweep steps R={r}", steps)
            self.run(f"sweep memory R={r}", memory)

    def project(self, setting: tuple[str, int, float]) -> None:
        """Hours for 2M steps per seed, S seeds vmapped: walk's fused step, with the env step
        of walk swapped for the task's at the setting's S * E worlds."""
        s, (name, e, _) = self.sizes, setting
        walk = s.tasks[0][1]
        for task, task_id in s.tasks:
            for arm, sirl in (("TDMPBC", True), ("TD-MPC2", False)):

                def fn(task=task, task_id=task_id, arm=arm, sirl=sirl):
                    seconds = self.per_step[name, sirl]  # KeyError: the train row failed
                    if task_id != walk:
                        worlds = SEEDS * e
                        seconds += self.env_step(task_id, worlds) - self.env_step(walk, worlds)
                    hours = RUN_STEPS / (e / seconds) / 3600
                    paper = paper_hours()[task]["TDMPBC" if sirl else "TD-MPC2"]
                    note = f"{s.caveat}paper (V100) {paper} h: {paper / hours:.3g}x faster"
                    if name != "paper":
                        note += f"; E={e} per seed, not the paper's setting"
                    return hours, "h", note

                self.run(f"project {task} {name} {arm}", fn)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes, for a CPU test")
    ap.add_argument("--json", default=None, help="also write the table as JSON to this file")
    ap.add_argument("--budget", type=float, default=None, help="seconds after which rows are "
                    "skipped (default 360; quick 600)")  # fmt: skip
    ap.add_argument("--rows", nargs="+", choices=ROW_GROUPS, default=None, metavar="GROUP",
                    help=f"only these groups of rows, in priority order (default all: "
                    f"{' '.join(ROW_GROUPS)}); the others read 'n/a: not reached'")  # fmt: skip
    args = ap.parse_args(argv)
    if args.quick:  # read when XLA's backend starts, i.e. at the first computation below
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {QUICK_XLA_FLAGS}".strip()
    sizes = Sizes.quick() if args.quick else Sizes()
    enable_compilation_cache()
    warp = warp_unavailable()
    header = {"backend": jax.default_backend(), "device": jax.devices()[0].device_kind,
              "quick": args.quick, "jax": jax.__version__, "warp": warp or "available"}  # fmt: skip
    print(f"device benchmark: {header}", file=sys.stderr, flush=True)
    table = Table(row_names(sizes), args.json, header)
    bench = Bench(sizes, table, args.budget or (600.0 if args.quick else 360.0))
    paper, throughput = sizes.settings
    _, probe = load(sizes.env_task)
    groups = {  # priority order: what the paper's projection needs first, Warp last
        "matmul": bench.matmul,
        "paper": lambda: (bench.train(paper), bench.project(paper)),
        "agent": lambda: bench.agent(probe.observation_size, probe.action_size),
        "env": lambda: [bench.env("jax", e, warp) for e in sizes.env_envs],
        "fasttd3": bench.fasttd3,
        "throughput": lambda: (bench.train(throughput), bench.project(throughput)),
        "sweep": bench.sweep,
        "warp": lambda: [bench.env("warp", e, warp) for e in sizes.env_envs],
    }
    chosen = set(args.rows or ROW_GROUPS)
    if "agent" in chosen:  # the agent rows' "x its matmul time" needs the matmul row
        chosen.add("matmul")
    for group in ROW_GROUPS:
        if group in chosen:
            groups[group]()
    table.write()
    table.print()
    print(f"\n{header}; {time.perf_counter() - bench.start:.0f} s")


if __name__ == "__main__":
    main()
