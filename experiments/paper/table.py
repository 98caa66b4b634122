"""The paper's results table: TDMPBC (beta 1) against TD-MPC2 (beta 0), 3 seeds a task.

    .venv/bin/python -m experiments.paper.table --scale cpu --tasks stand walk
    .venv/bin/python -m experiments.paper.table --scale paper          # all 14, on a GPU

Writes results/table/<task>/<arm>/ (see common.run_arm), results/table/table.csv (ours beside
the paper's, and whether each clears its bar) and results/table/table.png. Resumes.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import tyro

from experiments.paper.common import (
    ARMS,
    PAPER_TABLE,
    bar_plot,
    final_returns,
    run_arm,
    scale_config,
    write_summary,
)
from sirl_jax.envs import spec


@dataclasses.dataclass(frozen=True)
class Args:
    scale: str = "cpu"
    """paper (5M, 2M steps, h1hand; a GPU) | cpu (the CPU stand-in on the h1 variant)."""
    tasks: tuple[str, ...] = tuple(PAPER_TABLE)
    seeds: int = 3
    steps: int | None = None
    """Env steps per seed (default: 2M paper, 80k cpu)."""
    out: str = "results/table"


def main(args: Args) -> None:
    root, rows, bars, bar_lines = Path(args.out), [], {}, {}
    for task in args.tasks:
        if task not in PAPER_TABLE:
            allowed = ", ".join(PAPER_TABLE)
            raise SystemExit(f"error: --tasks {task!r} is invalid; allowed: {allowed}")
        ours = {}
        for arm, beta in ARMS.items():
            cfg = scale_config(args.scale, task, beta=beta, steps=args.steps)
            run_arm(cfg, args.seeds, root / task / arm, f"{task} {arm}")
            ours[arm] = final_returns(root / task / arm)
        bar = spec(cfg.train.task).success_bar
        paper_bar, paper_sirl, paper_plain = PAPER_TABLE[task]
        rows.append({
            "task": cfg.train.task, "scale": args.scale, "steps": cfg.train.steps,
            "tdmpbc_mean": round(ours["TDMPBC"].mean(), 2),
            "tdmpbc_std": round(ours["TDMPBC"].std(), 2),
            "tdmpc2_mean": round(ours["TD-MPC2"].mean(), 2),
            "tdmpc2_std": round(ours["TD-MPC2"].std(), 2),
            "bar": bar, "tdmpbc_clears_bar": bool(bar and ours["TDMPBC"].mean() >= bar),
            "paper_tdmpbc": f"{paper_sirl[0]} ± {paper_sirl[1]}",
            "paper_tdmpc2": f"{paper_plain[0]} ± {paper_plain[1]}", "paper_bar": paper_bar,
        })  # fmt: skip
        bars[task] = {a: (v.mean(), v.std()) for a, v in ours.items()}
        bar_lines[task] = bar
    write_summary(rows, root / "table.csv")
    bar_plot(bars, root / "table.png", "final eval return (planner)",
             f"TDMPBC vs TD-MPC2, {args.scale} scale; -- success bar", bar_lines)
    for r in rows:
        print(r)


if __name__ == "__main__":
    main(tyro.cli(Args))
