"""A sweep against processes side by side on this CPU, at the `cpu` preset's sizes.

    .venv/bin/python -m experiments.bench.bench_sweep            # R = 1, 2, 6 (about 10 min)
    .venv/bin/python -m experiments.bench.bench_sweep --runs 2   # one R

For each R: one process trains R runs as one program (a sirl.beta sweep, `sirl_jax.sweep`),
then R processes train one run each, side by side, timed over the same window (each waits for
the others' compiles before its timed chunks). The row is env steps/s per run of each, and the
ratio. Both use the `cpu` preset's agent (small model), E = 8, UTD 0.25 on the pendulum, the
fused step after its seed phase (`device_parts.train_seconds`). Run it on an idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a file: make `experiments` and `sirl_jax` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from experiments.bench.device_parts import Sizes, train_seconds
from sirl_jax.presets import get_preset
from sirl_jax.run.compile_cache import enable_compilation_cache

SIZES = Sizes(repeats=5)


def per_run_rate(runs: int, barrier: Path | None = None, peers: int = 1) -> float:
    """Env steps/s of each of `runs` runs in one program; with `barrier`, the timed chunks
    start once `peers` processes have compiled (each touches a file in that folder)."""
    cfg = get_preset("cpu")
    t = cfg.train
    if barrier is not None:  # compile and pass the seed phase first, then wait for the peers
        train_seconds(SIZES, t.task, t.num_envs, t.utd, True, cfg.agent, runs, True)
        (barrier / f"{os.getpid()}").touch()
        while len(list(barrier.iterdir())) < peers:
            time.sleep(0.2)
        train_seconds.cache_clear()
    seconds, _, bad = train_seconds(SIZES, t.task, t.num_envs, t.utd, True, cfg.agent, runs, True)
    if bad:
        raise FloatingPointError(f"{bad} non-finite losses or blow-ups")
    return t.num_envs * SIZES.train_chunk / seconds


def side_by_side(runs: int) -> float:
    """Mean env steps/s per run of `runs` one-run processes timed over the same window."""
    with tempfile.TemporaryDirectory() as barrier:
        cmd = [sys.executable, "-m", "experiments.bench.bench_sweep", "--one", barrier,
               "--peers", str(runs)]  # fmt: skip
        procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True) for _ in range(runs)]
        rates = []
        for p in procs:
            out, _ = p.communicate(timeout=1800)
            if p.returncode != 0:
                raise RuntimeError(f"a side-by-side process failed (exit {p.returncode})")
            rates.append(json.loads(out.strip().splitlines()[-1])["rate"])
    return sum(rates) / len(rates)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, nargs="+", default=[1, 2, 6])
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    ap.add_argument("--one", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--peers", type=int, default=1, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    enable_compilation_cache()
    if args.one is not None:  # a side-by-side process
        print(json.dumps({"rate": per_run_rate(1, args.one, args.peers)}), flush=True)
        return
    rows, t0 = [], time.perf_counter()
    for r in args.runs:
        sweep = per_run_rate(r)
        apart = side_by_side(r)
        rows.append({"runs": r, "sweep_per_run": round(sweep, 1),
                     "processes_per_run": round(apart, 1), "sweep_over_processes":
                     round(sweep / apart, 3)})  # fmt: skip
        print(f"{time.perf_counter() - t0:5.0f} s  R={r}: one program {sweep:.1f} env steps/s "
              f"per run, {r} processes side by side {apart:.1f} per run: "
              f"{sweep / apart:.2f}x", flush=True)  # fmt: skip
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
