"""The paper's beta ablation: beta in {0.5, 1, 2} (the paper found all three robust).

    .venv/bin/python -m experiments.paper.beta --scale cpu --tasks stand
    .venv/bin/python -m experiments.paper.beta --scale paper

Writes results/beta/<task>/<arm>/, results/beta/beta.csv and beta.png. Resumes.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import tyro

from experiments.paper.common import ablation


@dataclasses.dataclass(frozen=True)
class Args:
    scale: str = "cpu"
    """paper (5M, 2M steps, h1hand; a GPU) | cpu (the CPU stand-in on the h1 variant)."""
    tasks: tuple[str, ...] = ("run", "hurdle", "maze", "reach")
    """The paper's ablation tasks."""
    betas: tuple[float, ...] = (0.5, 1.0, 2.0)
    seeds: int = 3
    steps: int | None = None
    out: str = "results/beta"


def main(args: Args) -> None:
    arms = {f"beta={b:g}": {"beta": b} for b in args.betas}
    ablation(args.scale, args.tasks, args.seeds, args.steps, Path(args.out), arms,
             f"TDMPBC beta ablation, {args.scale} scale")  # fmt: skip


if __name__ == "__main__":
    main(tyro.cli(Args))
