"""Published HumanoidBench curves and the TDMPBC paper's numbers, for comparison with a run.

`sirl_jax/data/reference_curves.json` holds, with their sources named in the file:
  curves     TD-MPC2 (full 5M config) and BMPC eval return against env steps on the 14
             locomotion tasks (h1hand, 3 seeds, every 50k steps to 2M; mean and the source's
             confidence bounds), as released by the BMPC authors;
  paper_2m   the TDMPBC paper's table: TDMPBC and TD-MPC2 at 2M steps (mean, std), success bar;
  paper_hours_2m_3_seeds_v100   the paper's runtime table.
Only h1hand ids have references; the hand-less h1 variant and the manipulation tasks have none,
which `reference_curves` answers with an empty list and `missing_reason` explains in a line.
"""

from __future__ import annotations

import functools
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REFERENCE_FILE = Path(__file__).resolve().parent.parent / "data" / "reference_curves.json"
_H1HAND = re.compile(r"^h1hand-(?P<task>.+)-v0$")


@functools.cache
def load_reference() -> dict:
    """The reference file's contents (read once)."""
    return json.loads(REFERENCE_FILE.read_text())


@dataclass(frozen=True)
class ReferenceCurve:
    """One published curve: `algo` on `task` (HumanoidBench's short name); equal-length arrays."""

    algo: str
    task: str
    steps: np.ndarray
    mean: np.ndarray
    lcb: np.ndarray
    ucb: np.ndarray

    def until(self, max_steps: float) -> ReferenceCurve:
        """The curve up to the first point at or past `max_steps` (what a run's axes need)."""
        n = int(np.searchsorted(self.steps, max_steps, side="left")) + 1
        return ReferenceCurve(self.algo, self.task, self.steps[:n], self.mean[:n], self.lcb[:n],
                              self.ucb[:n])  # fmt: skip

    def at(self, steps: float) -> float:
        """The mean return at `steps`, linearly interpolated between published points."""
        return float(np.interp(steps, self.steps, self.mean))


def _short_name(task_id: str) -> str | None:
    match = _H1HAND.match(task_id)
    return match["task"] if match else None


def reference_curves(task_id: str) -> list[ReferenceCurve]:
    """The published curves of a task id (`h1hand-{task}-v0`), one per algorithm; [] if none."""
    task = _short_name(task_id)
    out = []
    for algo, tasks in load_reference()["curves"].items():
        if task in tasks:
            c = tasks[task]
            out.append(ReferenceCurve(algo, task, *(np.asarray(c[k], float)
                                                    for k in ("steps", "mean", "lcb", "ucb"))))
    return out


def missing_reason(task_id: str) -> str:
    """One line: why `task_id` has no reference curve (call when `reference_curves` is [])."""
    known = sorted(next(iter(load_reference()["curves"].values())))
    if _short_name(task_id) is None:
        return (f"no reference curve for {task_id}: the published curves are of the h1hand "
                f"robot (h1hand-TASK-v0, TASK one of {', '.join(known)})")
    return (f"no reference curve for {task_id}: published curves exist for the 14 locomotion "
            f"tasks only ({', '.join(known)})")


def paper_2m() -> dict[str, dict]:
    """The TDMPBC paper's table: {task: {"success_bar", "TDMPBC": [mean, std], "TD-MPC2": ...}}."""
    return load_reference()["paper_2m"]


def paper_hours() -> dict[str, dict]:
    """The paper's hours for 2M steps of 3 seeds on one V100: {task: {"TDMPBC", "TD-MPC2"}}."""
    return load_reference()["paper_hours_2m_3_seeds_v100"]


__all__ = ["REFERENCE_FILE", "ReferenceCurve", "load_reference", "missing_reason", "paper_2m",
           "paper_hours", "reference_curves"]  # fmt: skip
