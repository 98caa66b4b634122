"""The parallel-learner study's report: FastTD3 (beta 0) and FastTD3 + SIRL (beta 1) on
h1hand-sit_simple-v0 against wall-clock, beside the TD-MPC2 study.

    .venv/bin/python -m experiments.study parallel_learner --arm beta0 &   # 3 seeds, beta 0
    .venv/bin/python -m experiments.study parallel_learner --arm beta1 &   # 3 seeds, beta 1
    .venv/bin/python -m experiments.studies.parallel_learner \
        --results results/parallel_learner --out docs/results/parallel_learner

The arms are `experiments.studies.specs.STUDIES["parallel_learner"]`: the `fasttd3-cpu` preset
(32 envs per seed, batch 1024, critic 512, actor 256) at beta 0 or 1, the actor evaluated
(eval mode, 4 episodes) every 10k env steps per seed. Run them side by side, as the TD-MPC2
study's two arms ran, so that each has the same share of the machine.

This writes `<out>/summary.json` and `<out>/figure.png`: eval return against wall-clock
hours, process CPU hours and env steps for both arms and for the TD-MPC2 study's seeds
(planner eval), and, against env steps, the official FastTD3 at the arms' config
(`--official-log`), with the first time after step 0 that each seed reaches 10x the random
policy's mean return (`curves.hours_to`; `--random`, the sit_simple study's random.json).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import tyro

from experiments.studies.curves import eval_curves, hours_to
from experiments.studies.official_fasttd3 import official_rows
from experiments.studies.specs import SIT as TASK
from sirl_jax.run.runlog import CsvLog

ARMS = ("beta0", "beta1")


def summarize(results: Path, tdmpc2: Path, random_json: Path) -> dict:
    random = json.loads(random_json.read_text())
    bar = 10 * random["mean"]
    arms = {}
    for arm in ARMS:
        curves = eval_curves(results / arm, "policy_return")
        arms[arm] = {"final": [float(c["return"][-1]) for c in curves.values()],
                     "hours_to_10x": [hours_to(c, bar) for c in curves.values()],
                     "cpu_hours_to_10x": [hours_to(c, bar, "cpu_h") for c in curves.values()],
                     "final_steps": [int(c["steps"][-1]) for c in curves.values()]}  # fmt: skip
    td = eval_curves(tdmpc2, "planner_return")
    return {"task": TASK, "random_return": random["mean"], "arms": arms,
            "tdmpc2_hours_to_10x": [hours_to(c, bar) for c in td.values()],
            "tdmpc2_cpu_hours_to_10x": [hours_to(c, bar, "cpu_h") for c in td.values()],
            "tdmpc2_final_steps": [int(c["steps"][-1]) for c in td.values()]}  # fmt: skip


def figure(results: Path, tdmpc2: Path, bar: float, out: Path,
           zero_action: float | None = None, official: Path | None = None) -> None:
    """Each seed's eval return against wall-clock hours, process CPU hours and env steps; the
    last panel also draws the official FastTD3 run at the arms' config (`official`: its
    eval.csv), whose hours, on another process layout, are not comparable."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), sharey=True)
    series = [(results / "beta0", "policy_return", "tab:green", "FastTD3 (beta 0)"),
              (results / "beta1", "policy_return", "tab:purple", "FastTD3 + SIRL (beta 1)"),
              (tdmpc2, "planner_return", "tab:blue", "TD-MPC2 study (beta 0, planner)")]
    for ax, clock, xlabel in ((axes[0], "wall_h", "wall-clock hours (arms side by side)"),
                              (axes[1], "cpu_h", "process CPU hours (training)"),
                              (axes[2], "steps", "env steps per seed")):  # fmt: skip
        for d, column, color, label in series:
            for i, c in enumerate(eval_curves(d, column).values()):
                ax.plot(c[clock], c["return"], color=color, marker=".", lw=1,
                        label=label if i == 0 else None)  # fmt: skip
        ax.axhline(bar, color="k", lw=0.8, label=f"10x random ({bar:.0f})")
        if zero_action is not None:
            ax.axhline(zero_action, color="k", ls="--", lw=0.8,
                       label=f"zero action ({zero_action:.0f})")
        ax.set_xlabel(xlabel)
    if official is not None and official.exists():
        rows = CsvLog(official).rows()
        axes[2].plot([float(r["env_steps"]) for r in rows], [float(r["return"]) for r in rows],
                     color="tab:orange", marker="x", lw=1,
                     label="official FastTD3, same config, 1 seed")  # fmt: skip
        axes[2].legend(fontsize=7, loc="upper left")
    axes[0].set_ylabel("eval return (eval mode)")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{TASK}: each seed's eval return against time, 2-core CPU")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


@dataclasses.dataclass(frozen=True)
class Args:
    results: str = "results/parallel_learner"
    tdmpc2: str = "docs/results/sit_simple_study/study/tdmpc2"
    """The TD-MPC2 study arm drawn beside the FastTD3 arms."""
    random: str = "docs/results/sit_simple_study/random.json"
    """The random policy's return on the task (`sit_simple --random-episodes 64`)."""
    zero_action: str | None = "docs/results/sit_simple_study/zero_action.json"
    """The zero action's return on the task, drawn as a dashed line (None: not drawn)."""
    official_log: str | None = None
    """An official FastTD3 console log (`experiments.studies.official_fasttd3`): its
    evaluations go to `<out>/official_fasttd3/eval.csv` (drawn against env steps)."""
    out: str = "docs/results/parallel_learner"


def main(args: Args) -> None:
    root, out, tdmpc2 = Path(args.results), Path(args.out), Path(args.tdmpc2)
    summary = summarize(root, tdmpc2, Path(args.random))
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    official = out / "official_fasttd3" / "eval.csv"
    if args.official_log:
        official.parent.mkdir(parents=True, exist_ok=True)
        official.unlink(missing_ok=True)
        CsvLog(official).extend(official_rows(Path(args.official_log)))
    zero = json.loads(Path(args.zero_action).read_text())["mean"] if args.zero_action else None
    figure(root, tdmpc2, 10 * summary["random_return"], out / "figure.png", zero, official)
    for arm, v in summary["arms"].items():
        print(f"{arm}: final {np.round(v['final'], 1)} at {v['final_steps']} steps, hours to "
              f"10x {v['hours_to_10x']} (CPU hours {v['cpu_hours_to_10x']})")  # fmt: skip
    print(f"TD-MPC2: hours to 10x {summary['tdmpc2_hours_to_10x']} (CPU hours "
          f"{summary['tdmpc2_cpu_hours_to_10x']})")
    print(f"wrote {out / 'summary.json'} and {out / 'figure.png'}")


if __name__ == "__main__":
    main(tyro.cli(Args))
