"""The paper's G ablation: the reference return G = R_max (buffer) against R_target (bar).

    .venv/bin/python -m experiments.paper.g --scale cpu --tasks stand
    .venv/bin/python -m experiments.paper.g --scale paper

Writes results/g/<task>/<arm>/, results/g/g.csv and g.png. Resumes.
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
    seeds: int = 3
    steps: int | None = None
    out: str = "results/g"


def main(args: Args) -> None:
    arms = {"G=R_max": {"g_source": "rmax"}, "G=R_target": {"g_source": "target"}}
    ablation(args.scale, args.tasks, args.seeds, args.steps, Path(args.out), arms,
             f"TDMPBC reference return G, {args.scale} scale")  # fmt: skip


if __name__ == "__main__":
    main(tyro.cli(Args))
