"""The paper's tables from the arms `experiments.study` trained, and the humanoid study's figure.

    # each arm of each task first, e.g. the results table at CPU scale on stand and walk:
    .venv/bin/python -m experiments.study paper_table_cpu --task stand --arm TDMPBC
    .venv/bin/python -m experiments.studies.paper_report --study paper_table_cpu --tasks stand walk
    .venv/bin/python -m experiments.studies.paper_report --humanoid    # docs/results/humanoid_study

A table writes RESULTS/<study>/<study>.csv (per task and arm: the final planner return's mean
and std over seeds, each seed's; for paper_table_*, the paper's numbers and its bar beside
them) and <study>.png (grouped bars, the success bar dashed). --humanoid writes the humanoid
study's summary.csv, eval.csv and curves.png from RESULTS/humanoid_study/{tdmpc2,tdmpbc}.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import tyro

from experiments.studies.curves import eval_curves, final_returns, train_rows, write_summary


@dataclasses.dataclass(frozen=True)
class Args:
    study: str = "paper_table_cpu"
    tasks: tuple[str, ...] = ("stand",)
    results: str = "results"
    humanoid: bool = False
    out: str = "docs/results/humanoid_study"
    """Where --humanoid writes."""


def bar_plot(groups: dict[str, dict[str, tuple[float, float]]], path: Path, title: str,
             lines: dict[str, float]) -> None:  # fmt: skip
    """Grouped bars: {group (x tick): {series: (mean, std)}}; a dashed line per group."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names, series = list(groups), sorted({s for g in groups.values() for s in g})
    width = 0.8 / max(len(series), 1)
    fig, ax = plt.subplots(figsize=(max(4.0, 0.7 * len(names) * len(series) + 2), 4))
    for i, s in enumerate(series):
        xs = [j + (i - (len(series) - 1) / 2) * width for j in range(len(names))]
        ms = [groups[n].get(s, (math.nan, 0)) for n in names]
        ax.bar(xs, [m for m, _ in ms], width, yerr=[e for _, e in ms], label=s, capsize=3)
    for j, n in enumerate(names):
        if lines.get(n) is not None:
            ax.plot([j - 0.45, j + 0.45], [lines[n]] * 2, "k--", linewidth=1)
    ax.set_xticks(range(len(names)), names)
    ax.set(ylabel="final eval return (planner)", title=title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(study: str, tasks: tuple[str, ...], results: Path) -> list[dict]:
    from experiments.study import arm_config, study_of
    from sirl_jax.envs import spec
    from sirl_jax.run.reference import paper_2m

    s, paper = study_of(study), paper_2m()
    rows, bars, lines = [], {}, {}
    for task in tasks:
        bars[task] = {}
        for arm in s.arms:
            values = final_returns(results / study / task / arm)
            if not values.size:
                raise SystemExit(f"error: {results / study / task / arm} has no evaluations; "
                                 f"train it first: python -m experiments.study {study} "
                                 f"--task {task} --arm {arm}")  # fmt: skip
            cfg = arm_config(s, arm, task)
            bars[task][arm] = (values.mean(), values.std())
            row = {"task": cfg.train.task, "arm": arm, "steps": cfg.train.steps,
                   "mean": round(values.mean(), 2), "std": round(values.std(), 2),
                   "seeds": " ".join(f"{v:.2f}" for v in values)}  # fmt: skip
            if study.startswith("paper_table") and task in paper:
                ref = paper[task][arm]
                row.update(paper=f"{ref[0]} ± {ref[1]}", paper_bar=paper[task]["success_bar"])
            rows.append(row)
        lines[task] = spec(cfg.train.task).success_bar
    write_summary(rows, results / study / f"{study}.csv")
    bar_plot(bars, results / study / f"{study}.png", f"{study}; -- success bar", lines)
    for r in rows:
        print(r)
    return rows


def humanoid(results: Path, out: Path) -> None:
    """The humanoid study: each arm's seeds (thin) and mean ± std (thick) against env steps,
    the training-episode returns and TDMPBC's R_max, beside the random policy's return."""
    import jax
    import matplotlib

    from sirl_jax.envs import load
    from sirl_jax.evaluate import make_random_evaluate

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    task, arms = "h1-stand-v0", {"tdmpc2": 0.0, "tdmpbc": 1.0}
    m = jax.device_get(jax.jit(make_random_evaluate(load(task)[1], 64))(jax.random.PRNGKey(7)))
    rand = float(m["eval/random_return"])
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 4.2))
    summary, all_eval = [], []
    for i, (arm, beta) in enumerate(arms.items()):
        curves = eval_curves(results / arm, "planner_return")
        if not curves:
            print(f"{arm}: no results yet in {results / arm}")
            continue
        n = min(len(c["steps"]) for c in curves.values())
        steps = curves[0]["steps"][:n]
        grid = np.stack([c["return"][:n] for c in curves.values()])
        all_eval += [{"arm": arm, "seed": s, "env_steps": int(t), "planner_return": float(v)}
                     for s, c in curves.items()
                     for t, v in zip(c["steps"], c["return"], strict=True)]  # fmt: skip
        color = f"C{i}"
        for row in grid:
            ax0.plot(steps, row, color=color, alpha=0.35, linewidth=0.8)
        ax0.plot(steps, grid.mean(0), color=color, marker="o", label=f"{arm} (beta {beta:g})")
        ax0.fill_between(steps, grid.mean(0) - grid.std(0), grid.mean(0) + grid.std(0),
                         color=color, alpha=0.15)  # fmt: skip
        train = train_rows(results / arm)
        for s in curves:
            rows = [r for r in train if int(r["seed"]) == s]
            x = [int(r["env_steps"]) for r in rows]
            ax1.plot(x, [float(r["episode_return"] or "nan") for r in rows], color=color,
                     alpha=0.4, linewidth=0.6)  # fmt: skip
            if beta:
                ax1.plot(x, [float(r["r_max"] or "nan") for r in rows], color=color,
                         linestyle="--", linewidth=1)  # fmt: skip
        final = grid[:, -1]
        summary.append({
            "arm": arm, "beta": beta, "task": task, "env_steps_per_seed": int(steps[-1]),
            "final_planner_return_mean": round(final.mean(), 2),
            "final_planner_return_std": round(final.std(), 2),
            "final_planner_return_per_seed": " ".join(f"{v:.1f}" for v in final),
            "best_mean": round(grid.mean(0).max(), 2), "random_policy_return": round(rand, 2),
            "final_over_random_per_seed": " ".join(f"{v / rand:.2f}" for v in final),
            "wall_s": max(float(r["wall_s"]) for r in train),
        })  # fmt: skip
    ax0.axhline(rand, color="k", linestyle=":", linewidth=1, label=f"random policy ({rand:.1f})")
    ax0.axhline(3 * rand, color="grey", linestyle="-.", linewidth=1, label="3x random")
    ax0.set(xlabel="env steps per seed", ylabel="eval return (planner, 4 episodes)",
            title=f"{task}: 3 seeds each (thin), mean ± std (thick)")
    ax0.legend(fontsize=8)
    ax1.set(xlabel="env steps per seed", ylabel="return",
            title="training-episode return (solid), TDMPBC's buffer R_max (dashed)")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "curves.png", dpi=110)
    if summary:
        write_summary(summary, out / "summary.csv")
        write_summary(all_eval, out / "eval.csv")
    for row in summary:
        print(row)
    print(f"random policy on {task}: return {rand:.2f} (64 episodes); wrote {out}/")


def main(args: Args) -> None:
    if args.humanoid:
        humanoid(Path(args.results) / "humanoid_study", Path(args.out))
    else:
        table(args.study, args.tasks, Path(args.results))


if __name__ == "__main__":
    main(tyro.cli(Args))
