"""A study arm's evaluations and training rows, whichever driver wrote them.

Two layouts are read, and give the same rows:
- `experiments.study` (a sweep): ARM/sweep.json with runs ARM/seed=I/, or one seed per process,
  ARM/seedI/sweep.json with ARM/seedI/seed=I/; each run's eval.csv and metrics.csv as any
  run directory has them (`eval/policy_return`, `time/wall_s`, `time/train_cpu_s`, ...).
- the drivers before sweeps (the committed studies): ARM/eval.csv and ARM/train.csv with a
  `seed` column, or one per seed in ARM/seedI/.
Rows come back in the older layout's names: seed, env_steps, wall_s, cpu_s, planner_return,
policy_return, ..., r_max (eval); episode_return, episode_length, r_max, updates (train).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from sirl_jax.run.runlog import CsvLog

TRAIN_NAMES = {"episode/return": "episode_return", "episode/length": "episode_length",
               "r_max": "r_max", "updates": "updates"}  # fmt: skip


def _runs(arm_dir: Path) -> list[Path]:
    """The run directories of an arm written by `experiments.study`."""
    sweeps = [arm_dir] if (arm_dir / "sweep.json").is_file() else sorted(
        p.parent for p in arm_dir.glob("seed*/sweep.json"))  # fmt: skip
    return [s / name for s in sweeps for name in json.loads((s / "sweep.json").read_text())["runs"]]


def _seed(run_dir: Path) -> int:
    return int(json.loads((run_dir / "config.json").read_text())["train"]["seed"])


def _rows(arm_dir: Path, old: str, new: str, names: dict[str, str] | None) -> list[dict]:
    runs = _runs(arm_dir)
    if not runs:
        alone = sorted(arm_dir.glob(f"seed*/{old}"))  # one seed per process
        files = [arm_dir / old] if (arm_dir / old).exists() else alone
        return [r for f in files for r in CsvLog(f).rows()]
    out = []
    for run in runs:
        for r in CsvLog(run / new).rows() if (run / new).exists() else []:
            row = {"seed": _seed(run), "env_steps": r["env_steps"], "wall_s": r["time/wall_s"],
                   "cpu_s": r["time/train_cpu_s"]}  # fmt: skip
            for k, v in r.items():
                if names is None and k.startswith("eval/"):
                    row[k.removeprefix("eval/")] = "" if v == "nan" else v
                elif names is not None and k in names:
                    row[names[k]] = "" if v == "nan" else v
            out.append(row)
    return out


def has_evals(arm_dir: Path) -> bool:
    return bool(_runs(arm_dir)) or (arm_dir / "eval.csv").exists() or any(
        arm_dir.glob("seed*/eval.csv"))  # fmt: skip


def eval_rows(arm_dir: Path) -> list[dict]:
    """Every evaluation of every seed of the arm."""
    return _rows(arm_dir, "eval.csv", "eval.csv", None)


def train_rows(arm_dir: Path) -> list[dict]:
    """Every logged training row of every seed of the arm."""
    return _rows(arm_dir, "train.csv", "metrics.csv", TRAIN_NAMES)


def eval_curves(arm_dir: Path, column: str) -> dict[int, dict[str, np.ndarray]]:
    """{seed: {"steps", "return", "wall_h", "cpu_h", "r_max"}} of `column` by evaluation."""
    seeds: dict[int, dict[str, list]] = {}
    for r in eval_rows(arm_dir):
        d = seeds.setdefault(int(r["seed"]), {k: [] for k in ("steps", "return", "wall_h",
                                                             "cpu_h", "r_max")})  # fmt: skip
        d["steps"].append(int(r["env_steps"]))
        d["return"].append(float(r[column]) if r.get(column, "") != "" else np.nan)
        d["wall_h"].append(float(r["wall_s"]) / 3600)
        d["cpu_h"].append(float(r["cpu_s"]) / 3600)
        d["r_max"].append(float(r["r_max"]) if r.get("r_max", "") not in ("", "-inf") else np.nan)
    return {s: {k: np.asarray(v) for k, v in d.items()} for s, d in sorted(seeds.items())}


def hours_to(curve: dict[str, np.ndarray], bar: float, clock: str = "wall_h") -> float | None:
    """The hours of the first evaluation after training began (env steps > 0) whose return
    reaches `bar`; None if none does. The step-0 evaluation, of the untrained networks, never
    counts: on sit_simple an action near 0 already earns about 647 (the zero action's return),
    so FastTD3's untrained actor (a small output layer) and some TD-MPC2 seeds start above
    10x random (101.5) before learning anything."""
    hit = np.flatnonzero((curve["return"] >= bar) & (curve["steps"] > 0))
    return round(float(curve[clock][hit[0]]), 3) if hit.size else None


def final_returns(arm_dir: Path, column: str = "planner_return") -> np.ndarray:
    """[S] `column` at each seed's last evaluation."""
    return np.array([c["return"][-1] for c in eval_curves(arm_dir, column).values()])


def write_summary(rows: list[dict], path: Path) -> None:
    """Writes rows (dicts with the same keys) as a CSV."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
