"""Does a CPU preset learn robustly? 3 seeds vmapped, eval curve per seed, collapse check.

    .venv/bin/python -m experiments.studies.preset_robustness       # cpu, pendulum
    .venv/bin/python -m experiments.studies.preset_robustness --task dmc:CartpoleSwingup \
        --steps 60000

Runs the preset (sized for the task) with `experiments.paper.common.run_arm` under
results/robustness/<preset>-<task>/ (resumable), then prints per seed the best and final eval
planner return and whether the second half of the run has an evaluation below half of the
running best (`sirl_jax.run.plot.find_collapse`). Not a test: nothing is asserted.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import tyro

from experiments.paper.common import run_arm
from sirl_jax.envs import spec
from sirl_jax.presets import get_preset
from sirl_jax.run.config_rules import fit_to_task
from sirl_jax.run.plot import find_collapse
from sirl_jax.run.runlog import CsvLog


@dataclasses.dataclass(frozen=True)
class Args:
    preset: str = "cpu"
    task: str = "pendulum"
    steps: int | None = None
    seeds: int = 3


def main(args: Args) -> None:
    cfg = get_preset(args.preset)
    train = dataclasses.replace(cfg.train, task=args.task, steps=args.steps or cfg.train.steps)
    cfg, derived = fit_to_task(dataclasses.replace(cfg, train=train),
                               spec(args.task).episode_length)  # fmt: skip
    out = Path("results/robustness") / f"{args.preset}-{args.task.replace(':', '_')}"
    run_arm(cfg, args.seeds, out, f"{args.preset} {args.task}")
    rows = CsvLog(out / "eval.csv").rows()
    for s in range(args.seeds):
        mine = sorted((int(r["env_steps"]), float(r["planner_return"]))
                      for r in rows if int(r["seed"]) == s)  # fmt: skip
        steps, rets = np.array([m[0] for m in mine]), np.array([m[1] for m in mine])
        hit = find_collapse(steps, rets)
        if hit is None:
            verdict = "no collapse"
        else:
            half = "second" if hit[0] > steps[-1] / 2 else "first"
            verdict = f"collapse at {int(hit[0]):,} ({half} half) to {hit[1]:.1f}"
        print(f"seed {s}: best {rets.max():.1f} at {int(steps[rets.argmax()]):,}, "
              f"final {rets[-1]:.1f}; {verdict}")

if __name__ == "__main__":
    main(tyro.cli(Args))
