"""The sit_simple_solved study's summary.json and figure, from its arms' eval.csv (partial too).

    .venv/bin/python -m experiments.studies.sit_simple_solved_report --recipe transition \
        --results results/sit_simple_solved --out docs/results/sit_simple_solved

summary.json has the keys the write-up promises: task, success_bar, env_steps_per_seed,
eval_episodes and, per arm, each seed's final 16-episode return, the mean of its last three
evaluations, and the wall-clock hours to its first evaluation (after step 0) at the bar (None
if it never got there); `cpu_hours_to_bar` and `final_steps` come beside them. The figure draws
each seed against env steps with FastTD3's published curve (fasttd3_published.json, its seeds'
mean and range) and the published TD-MPC2 curve (`sirl_jax/data/reference_curves.json`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import tyro

from experiments.studies.parallel_learner import TASK, eval_curves, hours_to
from sirl_jax.run.reference import reference_curves

BAR, ZERO_ACTION = 750.0, 647.0  # HumanoidBench's bar; the zero action's return (the issue's)
ARM_LABELS = {"beta0": ("FastTD3 (beta 0)", "tab:green"),
              "beta1": ("FastTD3 + TDMPBC term (beta 1)", "tab:purple")}  # fmt: skip


def summarize(root: Path) -> dict:
    arms, steps = {}, []
    for arm in ARM_LABELS:
        if not (root / arm / "eval.csv").exists():
            continue
        curves = eval_curves(root / arm, "policy_return").values()
        arms[arm] = {
            "final": [round(float(c["return"][-1]), 1) for c in curves],
            "last3_mean": [round(float(np.mean(c["return"][-3:])), 1) for c in curves],
            "hours_to_bar": [hours_to(c, BAR) for c in curves],
            "cpu_hours_to_bar": [hours_to(c, BAR, "cpu_h") for c in curves],
            "final_steps": [int(c["steps"][-1]) for c in curves],
        }
        steps += arms[arm]["final_steps"]
    config = json.loads(next(root.glob("*/config.json")).read_text())
    return {"task": TASK, "success_bar": int(BAR), "env_steps_per_seed": min(steps, default=0),
            "eval_episodes": config["train"]["eval_episodes"], "arms": arms}  # fmt: skip


def figure(root: Path, published: Path, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.8))
    last = 0
    for arm, (label, color) in ARM_LABELS.items():
        if not (root / arm / "eval.csv").exists():
            continue
        for i, c in enumerate(eval_curves(root / arm, "policy_return").values()):
            ax.plot(c["steps"], c["return"], color=color, marker=".", lw=1,
                    label=label if i == 0 else None)  # fmt: skip
            last = max(last, int(c["steps"][-1]))
    pub = json.loads(published.read_text())
    ax.plot(pub["env_step"], pub["return"], color="tab:orange", marker="s", lw=1.5,
            label="FastTD3, published (its settings, mean of seeds)")  # fmt: skip
    ax.fill_between(pub["env_step"], pub["return_min"], pub["return_max"], color="tab:orange",
                    alpha=0.15)  # fmt: skip
    for curve in reference_curves(TASK):
        if curve.algo == "TD-MPC2":
            ax.plot(curve.steps, curve.mean, color="tab:blue", lw=1.5,
                    label="TD-MPC2, published (5M model)")  # fmt: skip
            ax.fill_between(curve.steps, curve.lcb, curve.ucb, color="tab:blue", alpha=0.12)
    ax.axhline(BAR, color="k", lw=0.9, label=f"success bar ({BAR:.0f})")
    ax.axhline(ZERO_ACTION, color="k", ls="--", lw=0.8, label=f"zero action ({ZERO_ACTION:.0f})")
    ax.set_xlim(0, max(2.5 * last, 1_300_000))
    ax.set(xlabel="env steps per seed", ylabel="eval return (16 episodes, eval mode)",
           title=f"{TASK}: FastTD3 with and without the TDMPBC term, 2-core CPU")  # fmt: skip
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(recipe: str = "transition", results: Path = Path("results/sit_simple_solved"),
         out: Path = Path("docs/results/sit_simple_solved")) -> None:  # fmt: skip
    """Writes `out`/summary.json and `out`/figure.png for `recipe`'s arms under `results`."""
    root = results / recipe
    if not any((root / arm / "eval.csv").exists() for arm in ARM_LABELS):
        raise SystemExit(f"error: no arm of {root} has an eval.csv yet (run --arm beta1 first)")
    summary = summarize(root)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    figure(root, out / "fasttd3_published.json", out / "figure.png")
    for arm, v in summary["arms"].items():
        print(f"{arm}: final {v['final']} last3 {v['last3_mean']} at {v['final_steps']} steps; "
              f"hours to bar {v['hours_to_bar']}")  # fmt: skip
    print(f"wrote {out / 'summary.json'} and {out / 'figure.png'}")


if __name__ == "__main__":
    tyro.cli(main)
