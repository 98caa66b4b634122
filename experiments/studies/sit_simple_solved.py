"""h1hand-sit_simple-v0 past HumanoidBench's bar (750) with FastTD3 + the TDMPBC term.

    # the pilot: one seed per recipe at equal training CPU time, 16 episodes every 10k
    .venv/bin/python -m experiments.studies.sit_simple_solved --pilot base --budget-cpu-s 2000
    .venv/bin/python -m experiments.studies.sit_simple_solved --pilot-report
    # the study: 3 seeds per arm of the chosen recipe, 16 episodes every 20k
    .venv/bin/python -m experiments.studies.sit_simple_solved --arm beta1 --recipe transition
    # or one seed per process (about 1.4 h each on 2 cores; the key it has in the 3-seed run)
    .venv/bin/python -m experiments.studies.sit_simple_solved --arm beta1 --recipe transition \
        --seed 0

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
SEEDS = 3
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


def pilot_rows(results: Path) -> list[dict]:
    """Each recipe's 16-episode evaluations at equal training CPU: up to the CPU time every
    recipe's run has reached, the later half of it summarised (mean, min, max, evaluations at
    the bar, mean change between consecutive evaluations), with the first one at the bar."""
    curves = {}
    for name in RECIPES:
        if (results / name / "eval.csv").exists():
            (curves[name],) = eval_curves(results / name, "policy_return").values()
    limit = min(float(c["cpu_h"][-1]) for c in curves.values())
    rows = []
    for name, c in curves.items():
        keep = (c["cpu_h"] <= limit + 1e-9) & (c["steps"] > 0)
        late = keep & (c["cpu_h"] >= limit / 2)
        r = c["return"][late]
        hit = np.flatnonzero(keep & (c["return"] >= BAR))
        rows.append({
            "recipe": name, "cpu_h": round(limit, 3), "evals_late": int(late.sum()),
            "steps_at_limit": int(c["steps"][keep][-1]), "late_mean": round(float(r.mean()), 1),
            "late_min": round(float(r.min()), 1), "late_max": round(float(r.max()), 1),
            "late_at_bar": int(np.sum(r >= BAR)),
            "swing": round(float(np.mean(np.abs(np.diff(r)))), 1) if r.size > 1 else None,
            "last": round(float(c["return"][keep][-1]), 1),
            "first_bar_steps": int(c["steps"][hit[0]]) if hit.size else None,
        })  # fmt: skip
    return rows


def main(pilot: str | None = None, budget_cpu_s: float = 2000.0, arm: str | None = None,
         recipe: str = "base", steps: int = 400_000, pilot_report: bool = False,
         results: Path = Path("results/sit_simple_solved"),
         seed: int | None = None) -> None:  # fmt: skip
    """--pilot RECIPE: one seed of RECIPE at beta 1 until `budget_cpu_s` of training CPU;
    --pilot-report: the pilot's table at equal training CPU (`pilot_rows`) as pilot.json;
    --arm beta0|beta1: the study's 3 seeds of `recipe` for `steps` env steps per seed, in one
    program, or with --seed I only seed I (0-2), in RECIPE/ARM/seedI."""
    if pilot is not None:
        cfg = config(pilot, 1.0, 300_000, eval_every=10_000, episodes=16)
        run_arm(cfg, 1, results / "pilot" / pilot, f"pilot {pilot}",
                budget_cpu_s=budget_cpu_s, keep=None if pilot == "base" else 2)  # fmt: skip
    elif pilot_report:
        rows = pilot_rows(results / "pilot")
        (results / "pilot" / "pilot.json").write_text(json.dumps(rows, indent=1))
        for r in rows:
            print(r)
    elif arm in ("beta0", "beta1"):
        cfg = config(recipe, float(arm[-1]), steps, eval_every=20_000, episodes=16)
        if seed is None:
            run_arm(cfg, SEEDS, results / recipe / arm, f"{recipe} {arm}")
        elif 0 <= seed < SEEDS:
            run_arm(cfg, SEEDS, results / recipe / arm / f"seed{seed}",
                    f"{recipe} {arm} seed {seed}", only=(seed,))  # fmt: skip
        else:
            raise SystemExit(f"error: --seed {seed} is invalid; allowed: 0..{SEEDS - 1}")
    else:
        raise SystemExit(f"error: --arm {arm!r} is invalid; allowed: beta0, beta1 (or --pilot "
                         "RECIPE, --pilot-report)")  # fmt: skip


if __name__ == "__main__":
    tyro.cli(main)
