"""The paper's runtime table: wall-clock of TDMPBC and TD-MPC2 for 2M steps of 3 seeds.

    .venv/bin/python -m experiments.paper.runtime --scale cpu
    .venv/bin/python -m experiments.paper.runtime --scale paper     # on a GPU

For each task and arm, 3 seeds run vmapped in one program (as the paper ran them side by side)
for `--chunks` chunks after the seed phase; the steady env steps/s (per seed; the first
planning chunk, which compiles and pretrains, is left out) gives the projection
2M / rate hours, beside the paper's V100 hours. Writes results/runtime/runtime.{csv,png}.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import tyro

from experiments.paper.common import (
    ARMS,
    PAPER_HOURS,
    bar_plot,
    run_arm,
    scale_config,
    write_summary,
)


@dataclasses.dataclass(frozen=True)
class Args:
    scale: str = "cpu"
    tasks: tuple[str, ...] = ("walk", "reach", "hurdle")
    seeds: int = 3
    chunks: int = 8
    """Chunks timed after the seed phase (the first is dropped as compile + pretraining)."""
    out: str = "results/runtime"


def main(args: Args) -> None:
    root, rows, bars = Path(args.out), [], {}
    for task in args.tasks:
        bars[task] = {}
        for arm, beta in ARMS.items():
            cfg = scale_config(args.scale, task, beta=beta)
            # Time only: the seed phase, then `chunks` planning chunks; the state is not kept.
            seed_chunks = -(-cfg.train.resolved_seed_steps(1000) // cfg.train.steps_per_call)
            probe = root / task / arm
            shutil.rmtree(probe, ignore_errors=True)
            summary = run_arm(cfg, args.seeds, probe, f"{task} {arm}",
                              max_chunks=seed_chunks + args.chunks)  # fmt: skip
            shutil.rmtree(probe / "checkpoints", ignore_errors=True)
            rate = summary["env_steps_per_s_per_seed"]
            hours = 2_000_000 / rate / 3600 if rate and math.isfinite(rate) else math.nan
            paper = PAPER_HOURS.get(task, (math.nan, math.nan))[0 if beta else 1]
            rows.append({"task": cfg.train.task, "arm": arm, "scale": args.scale,
                         "seeds": args.seeds, "env_steps_per_s_per_seed": rate,
                         "hours_per_2M_steps_3_seeds": round(hours, 2),
                         "paper_v100_hours": paper,
                         "speedup_vs_paper": round(paper / hours, 2) if hours else math.nan})
            bars[task][arm] = (hours, 0.0)
    write_summary(rows, root / "runtime.csv")
    bar_plot(bars, root / "runtime.png", "hours for 2M steps x 3 seeds",
             f"projected wall-clock, {args.scale} scale (paper V100: ~36-38 h)")  # fmt: skip
    for r in rows:
        print(r)


if __name__ == "__main__":
    main(tyro.cli(Args))
