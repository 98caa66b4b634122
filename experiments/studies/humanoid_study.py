"""The first humanoid study: TD-MPC2 (beta = 0) against TDMPBC (beta = 1) at CPU scale.

    .venv/bin/python -m experiments.studies.humanoid_study --arm tdmpc2  # beta 0, 3 seeds vmapped
    .venv/bin/python -m experiments.studies.humanoid_study --arm tdmpbc  # beta 1, 3 seeds vmapped
    .venv/bin/python -m experiments.studies.humanoid_study --report      # CSV + PNG, docs/results

Config: `experiments.paper.common.scale_config("cpu", "stand")`, the `cpu` preset's agent
(latent 64, MLP 128, 2 Qs, MPPI 64 samples x 2 iterations, horizon 3, batch 64) on
h1-stand-v0 (the H1 without hands: 19 actuators, 51-D observation), 4 envs per seed, UTD 0.25,
5,000 seed steps, 80k env steps per seed, evaluations (4 episodes, eval mode) every 20k.
Each arm is one program (3 seeds vmapped) and resumes where it stopped
(`experiments.paper.common.run_arm`). `--report` reads only the CSVs, measures the random
policy's mean episode return on the task (64 episodes), and writes
docs/results/humanoid_study/{summary.csv,eval.csv,curves.png}.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import tyro

from experiments.paper.common import run_arm, scale_config, write_summary
from sirl_jax.run.runlog import CsvLog

ARMS = {"tdmpc2": 0.0, "tdmpbc": 1.0}
OUT = Path("docs/results/humanoid_study")


@dataclasses.dataclass(frozen=True)
class Args:
    arm: str | None = None
    """tdmpc2 (beta 0) or tdmpbc (beta 1): run (or resume) that arm."""
    report: bool = False
    """Write the summary, the curves and the random baseline from the arms' CSVs."""
    results: str = "results/humanoid_study"
    """Where the arms write (one directory per arm)."""
    seeds: int = 3
    steps: int = 80_000


def _rows(path: Path) -> list[dict]:
    return CsvLog(path).rows()


def random_return(task: str, episodes: int = 64) -> tuple[float, float]:
    """Mean and std of the uniform random policy's episode return (first episodes)."""
    import jax

    from sirl_jax.envs import load
    from sirl_jax.evaluate import make_random_evaluate

    _, env = load(task)
    m = jax.device_get(jax.jit(make_random_evaluate(env, episodes))(jax.random.PRNGKey(7)))
    return float(m["eval/random_return"]), float(m["eval/random_length"])


def report(args: Args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    task = scale_config("cpu", "stand").train.task
    rand, rand_len = random_return(task)
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 4.2))
    summary, all_eval = [], []
    for i, arm in enumerate(ARMS):
        root = Path(args.results) / arm
        if not (root / "eval.csv").exists():
            print(f"{arm}: no results yet in {root}")
            continue
        ev, tr = _rows(root / "eval.csv"), _rows(root / "train.csv")
        all_eval += [{"arm": arm, **r} for r in ev]
        seeds = sorted({int(r["seed"]) for r in ev})
        steps = sorted({int(r["env_steps"]) for r in ev})
        grid = np.array([[float(next(r["planner_return"] for r in ev if int(r["seed"]) == s
                                     and int(r["env_steps"]) == t)) for t in steps]
                         for s in seeds])  # fmt: skip
        color = f"C{i}"
        for row in grid:
            ax0.plot(steps, row, color=color, alpha=0.35, linewidth=0.8)
        ax0.plot(steps, grid.mean(0), color=color, marker="o", label=f"{arm} (beta {ARMS[arm]:g})")
        ax0.fill_between(steps, grid.mean(0) - grid.std(0), grid.mean(0) + grid.std(0),
                         color=color, alpha=0.15)  # fmt: skip
        for s in seeds:
            rows = [r for r in tr if int(r["seed"]) == s]
            x = [int(r["env_steps"]) for r in rows]
            ret = [float(r["episode_return"]) if r["episode_return"] else math.nan for r in rows]
            ax1.plot(x, ret, color=color, alpha=0.4, linewidth=0.6)
            if arm == "tdmpbc":
                r_max = [float(r["r_max"]) if r["r_max"] not in ("", "-inf") else math.nan
                         for r in rows]  # fmt: skip
                ax1.plot(x, r_max, color=color, linestyle="--", linewidth=1)
        final = grid[:, -1]
        summary.append({
            "arm": arm, "beta": ARMS[arm], "task": task, "env_steps_per_seed": steps[-1],
            "final_planner_return_mean": round(final.mean(), 2),
            "final_planner_return_std": round(final.std(), 2),
            "final_planner_return_per_seed": " ".join(f"{v:.1f}" for v in final),
            "best_mean": round(grid.mean(0).max(), 2),
            "random_policy_return": round(rand, 2),
            "final_over_random_per_seed": " ".join(f"{v / rand:.2f}" for v in final),
            "wall_s": max(float(r["wall_s"]) for r in tr),
        })  # fmt: skip
    ax0.axhline(rand, color="k", linestyle=":", linewidth=1, label=f"random policy ({rand:.1f})")
    ax0.axhline(3 * rand, color="grey", linestyle="-.", linewidth=1, label="3x random")
    ax0.set(xlabel="env steps per seed", ylabel="eval return (planner, 4 episodes)",
            title=f"{task}: 3 seeds each (thin), mean ± std (thick)")
    ax0.legend(fontsize=8)
    ax1.set(xlabel="env steps per seed", ylabel="return",
            title="training-episode return (solid), TDMPBC's buffer R_max (dashed)")
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT / "curves.png", dpi=110)
    if summary:
        write_summary(summary, OUT / "summary.csv")
        with open(OUT / "eval.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(all_eval[0]))
            writer.writeheader()
            writer.writerows(all_eval)
    for row in summary:
        print(row)
    print(f"random policy on {task}: return {rand:.2f}, episode length {rand_len:.1f} "
          f"(64 episodes); wrote {OUT}/")  # fmt: skip


def main(args: Args) -> None:
    if args.report:
        report(args)
        return
    if args.arm not in ARMS:
        raise SystemExit(f"error: --arm {args.arm!r} is invalid; allowed: {', '.join(ARMS)}")
    cfg = scale_config("cpu", "stand", beta=ARMS[args.arm], steps=args.steps)
    run_arm(cfg, args.seeds, Path(args.results) / args.arm, args.arm)


if __name__ == "__main__":
    main(tyro.cli(Args))
