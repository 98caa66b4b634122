"""h1hand-sit_simple-v0 past HumanoidBench's bar (750) with FastTD3 + the TDMPBC term.

    # the pilot: one seed per recipe at equal training CPU time, 16 episodes every 10k
    .venv/bin/python -m experiments.studies.sit_simple_solved --pilot base --budget-cpu-s 2000
    .venv/bin/python -m experiments.studies.sit_simple_solved --pilot-report
    # the study: 3 seeds per arm of the chosen recipe, 16 episodes every 20k
    .venv/bin/python -m experiments.studies.sit_simple_solved --arm beta1 --recipe ema
    .venv/bin/python -m experiments.studies.sit_simple_solved --arm beta0 --recipe ema

Every run is the `fasttd3-cpu` preset (32 envs, batch 1024, critic 512, actor 256) on the env
the parallel-learner study used (`STUDY_ENV`), with one recipe's FastTD3 fields replaced
(`RECIPES`). The pilot's base recipe keeps every checkpoint, for the probe of consecutive
checkpoints (`experiments.studies.sit_simple_probe`). Runs resume where they stopped
(`experiments.paper.common.run_arm`).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import tyro

from experiments.paper.common import run_arm
from experiments.studies.parallel_learner import config as parallel_config
from experiments.studies.parallel_learner import eval_curves
from sirl_jax.config import Config

BAR = 750.0
RECIPES: dict[str, dict] = {
    # the recipe of the parallel-learner study: episode-uniform replay (TD-MPC2's sampler)
    "base": {"replay_sampling": "episode"},
    # an averaged actor acts and is evaluated (rate 0.005: about 200 actor updates)
    "ema": {"replay_sampling": "episode", "actor_ema": 0.005},
    # FastTD3's transition-uniform replay (the fasttd3 default since the diagnosis)
    "transition": {"replay_sampling": "transition"},
    "transition_ema": {"replay_sampling": "transition", "actor_ema": 0.005},
}
"""The pilot's candidates: `fasttd3` field overrides of the fasttd3-cpu preset."""


def config(recipe: str, beta: float, steps: int, eval_every: int, episodes: int) -> Config:
    """The parallel-learner study's config at `beta` with `recipe`'s FastTD3 fields."""
    if recipe not in RECIPES:
        raise SystemExit(f"error: --recipe {recipe!r} is invalid; allowed: {', '.join(RECIPES)}")
    cfg = parallel_config(beta, steps)
    fasttd3 = dataclasses.replace(cfg.agent.fasttd3, **RECIPES[recipe])
    train = dataclasses.replace(cfg.train, eval_every=eval_every, eval_episodes=episodes)
    return dataclasses.replace(cfg, agent=dataclasses.replace(cfg.agent, fasttd3=fasttd3),
                               train=train)  # fmt: skip


def pilot_row(name: str, run_dir: Path, from_steps: int) -> dict:
    """One recipe's pilot figures: its 16-episode evaluations after `from_steps` env steps."""
    (c,) = eval_curves(run_dir, "policy_return").values()
    late = c["return"][c["steps"] >= from_steps]
    swing = np.abs(np.diff(late)) if late.size > 1 else np.array([np.nan])
    return {"recipe": name, "evals": int(late.size), "last_steps": int(c["steps"][-1]),
            "mean": round(float(np.mean(late)), 1), "min": round(float(np.min(late)), 1),
            "max": round(float(np.max(late)), 1), "at_bar": int(np.sum(late >= BAR)),
            "swing": round(float(np.mean(swing)), 1), "final": round(float(late[-1]), 1),
            "first_bar_steps": next((int(s) for s, r in zip(c["steps"], c["return"], strict=True)
                                     if s > 0 and r >= BAR), None)}  # fmt: skip


def main(pilot: str | None = None, budget_cpu_s: float = 2000.0, arm: str | None = None,
         recipe: str = "base", steps: int = 400_000, pilot_report: bool = False,
         pilot_from: int = 100_000,
         results: Path = Path("results/sit_simple_solved")) -> None:  # fmt: skip
    """--pilot RECIPE: one seed of RECIPE at beta 1 until `budget_cpu_s` of training CPU;
    --pilot-report: the pilot's table (evaluations after `pilot_from` steps) as pilot.json;
    --arm beta0|beta1: the study's 3 seeds of `recipe` for `steps` env steps per seed."""
    if pilot is not None:
        cfg = config(pilot, 1.0, 300_000, eval_every=10_000, episodes=16)
        run_arm(cfg, 1, results / "pilot" / pilot, f"pilot {pilot}",
                budget_cpu_s=budget_cpu_s, keep=None if pilot == "base" else 2)  # fmt: skip
    elif pilot_report:
        rows = [pilot_row(n, results / "pilot" / n, pilot_from) for n in RECIPES
                if (results / "pilot" / n / "eval.csv").exists()]  # fmt: skip
        (results / "pilot" / "pilot.json").write_text(json.dumps(rows, indent=1))
        for r in rows:
            print(r)
    elif arm in ("beta0", "beta1"):
        cfg = config(recipe, float(arm[-1]), steps, eval_every=20_000, episodes=16)
        run_arm(cfg, 3, results / recipe / arm, f"{recipe} {arm}")
    else:
        raise SystemExit(f"error: --arm {arm!r} is invalid; allowed: beta0, beta1 (or --pilot "
                         "RECIPE, --pilot-report)")  # fmt: skip


if __name__ == "__main__":
    tyro.cli(main)
