"""`plot RUN_DIR...`: learning curves, the paper's R_max figure and normalised scores (one PNG).

Inputs are a run directory's own files: config.json, metrics.csv (training chunks: r_max,
episode/return) and the evaluations, from `eval` (eval/checkpoints.csv, N episodes per
checkpoint) when present, else the ones logged during training (eval.csv). Runs whose configs
differ only in the seed form one group, drawn as mean ± std over its seeds at the env steps
all of them evaluated.

Panels:
  1. eval return against env steps per group; the task's success bar dashed, the random
     policy's mean return (eval/random.csv, written by `eval`) dotted; a collapse (eval return
     below half its running best) is marked and printed;
  2. the TDMPBC paper's Fig. 8: the buffer's R_max and the training-episode return against env
     steps (metrics.csv);
  3. with runs of several tasks: the final eval return over the success bar per task (Fig. 2).

With `reference=True` panel 1 also draws the published curves of each run's task
(`sirl_jax.run.reference`: TD-MPC2 and BMPC on h1hand, mean and confidence band) up to the runs'
last env step; a task without one gets a one-line note.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sirl_jax.config import flatten_config
from sirl_jax.run import runlog
from sirl_jax.run.errors import UsageError
from sirl_jax.run.runlog import CsvLog


@dataclass
class RunCurves:
    """What one run directory contributes to the plots."""

    path: Path
    task: str
    seed: int
    group: tuple  # the flattened config without the seed
    eval_steps: np.ndarray
    eval_return: np.ndarray  # planner return (policy prior when the agent does not plan)
    train_steps: np.ndarray = field(default_factory=lambda: np.zeros(0))
    r_max: np.ndarray = field(default_factory=lambda: np.zeros(0))
    train_return: np.ndarray = field(default_factory=lambda: np.zeros(0))
    random_return: float = math.nan


def _column(rows: list[dict], name: str) -> np.ndarray:
    return np.array([float(r[name]) if r.get(name) not in (None, "") else math.nan for r in rows])


def load_run(path: Path) -> RunCurves:
    """Reads one run directory (UsageError when it is not one or has no evaluation)."""
    if not path.is_dir():
        raise UsageError(f"run directory {path} does not exist")
    config = runlog.load_config(path)
    rows = CsvLog(path / "eval" / "checkpoints.csv").rows() or CsvLog(path / "eval.csv").rows()
    if not rows:
        raise UsageError(f"{path} has no evaluations yet (eval.csv, or run `eval {path}`)")
    key = "eval/planner_return" if "eval/planner_return" in rows[0] else "eval/policy_return"
    steps = _column(rows, "env_steps")
    order = np.argsort(steps, kind="stable")
    flat = flatten_config(config)
    flat.pop("train.seed")
    metrics = CsvLog(path / "metrics.csv").rows()
    random_rows = CsvLog(path / "eval" / "random.csv").rows()
    return RunCurves(
        path=path, task=config.train.task, seed=config.train.seed,
        group=tuple(sorted((k, repr(v)) for k, v in flat.items())),
        eval_steps=steps[order], eval_return=_column(rows, key)[order],
        train_steps=_column(metrics, "env_steps"), r_max=_column(metrics, "r_max"),
        train_return=_column(metrics, "episode/return"),
        random_return=float(_column(random_rows, "eval/random_return")[-1])
        if random_rows else math.nan,
    )  # fmt: skip


def group_runs(runs: Sequence[RunCurves]) -> list[list[RunCurves]]:
    """Runs sharing a config except the seed, in first-seen order."""
    groups: dict[tuple, list[RunCurves]] = {}
    for run in runs:
        groups.setdefault(run.group, []).append(run)
    return list(groups.values())


def mean_std(group: Sequence[RunCurves]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(env steps evaluated by every run of the group, mean, population std) of eval return."""
    common = set(group[0].eval_steps.tolist())
    for run in group[1:]:
        common &= set(run.eval_steps.tolist())
    steps = np.array(sorted(common))
    values = np.stack([[r.eval_return[r.eval_steps == s][-1] for s in steps] for r in group])
    return steps, values.mean(axis=0), values.std(axis=0)


def find_collapse(steps: np.ndarray, returns: np.ndarray) -> tuple[float, float, float] | None:
    """The first (env step, return, running best) where the return falls below half its
    running best (best > 0), or None."""
    best = -math.inf
    for s, r in zip(steps, returns, strict=True):
        if best > 0 and r < 0.5 * best:
            return float(s), float(r), float(best)
        best = max(best, r)
    return None


def _label(group: Sequence[RunCurves], all_groups: Sequence[Sequence[RunCurves]]) -> str:
    """The task plus the config fields that differ between the plotted groups."""
    differing = set()
    for other in all_groups:
        differing |= set(group[0].group) ^ set(other[0].group)
    own = dict(group[0].group)
    fields = sorted({k for k, _ in differing} - {"train.task"})
    parts = [f"{k.rsplit('.', 1)[-1]}={own[k]}" for k in fields if k in own][:3]
    return f"{group[0].task} " + " ".join(parts) + f" ({len(group)} seed{'s' * (len(group) > 1)})"


def _draw_references(ax, tasks: Sequence[str], runs: Sequence[RunCurves]) -> list[str]:
    """The published curves of `tasks` on `ax`, up to the runs' last env step; returns the note
    lines of tasks without one."""
    from sirl_jax.envs import spec
    from sirl_jax.run.reference import missing_reason, reference_curves

    notes, styles = [], {"TD-MPC2": ("0.35", "--"), "BMPC": ("tab:olive", "-.")}
    for task in tasks:
        try:
            task_id = spec(task).id
        except KeyError:
            task_id = task
        curves = reference_curves(task_id)
        if not curves:
            notes.append(f"note: {missing_reason(task_id)}")
            continue
        last = max(float(r.eval_steps.max()) for r in runs if r.task == task)
        for curve in curves:
            c = curve.until(last)
            color, style = styles.get(c.algo, ("0.5", ":"))
            ax.plot(c.steps, c.mean, color=color, linestyle=style, linewidth=1.2,
                    label=f"{c.algo} reference, h1hand-{c.task} (published, 3 seeds)")
            ax.fill_between(c.steps, c.lcb, c.ucb, color=color, alpha=0.08)
    return notes


def plot(run_dirs: Sequence[Path], out: Path, reference: bool = False) -> list[str]:
    """Writes the PNG; returns the warning lines (collapses) and, with `reference`, the note
    lines of tasks without a reference curve, all of which it printed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sirl_jax.envs import spec

    paths = [r for p in map(Path, run_dirs) for r in (runlog.sweep_runs(p) or [p])]
    runs = [load_run(p) for p in paths]  # a sweep directory: its runs
    groups = group_runs(runs)
    tasks = sorted({r.task for r in runs})
    panels = 3 if len(tasks) > 1 else 2
    fig, axes = plt.subplots(1, panels, figsize=(6 * panels, 4.2))
    warnings, finals = [], {}
    for i, group in enumerate(groups):
        color = f"C{i % 10}"
        steps, mean, std = mean_std(group)
        label = _label(group, groups)
        axes[0].plot(steps, mean, color=color, marker=".", label=label)
        axes[0].fill_between(steps, mean - std, mean + std, color=color, alpha=0.2)
        for run in group:
            hit = find_collapse(run.eval_steps, run.eval_return)
            if hit is not None:
                warnings.append(f"warning: {run.path}: eval return {hit[1]:.1f} at env step "
                                f"{hit[0]:,.0f} is below half its best {hit[2]:.1f}")  # fmt: skip
                axes[0].plot([hit[0]], [hit[1]], "x", color=color, markersize=10)
        random = np.nanmean([r.random_return for r in group]) if any(
            math.isfinite(r.random_return) for r in group) else math.nan  # fmt: skip
        if math.isfinite(random):
            axes[0].axhline(random, color=color, linestyle=":", linewidth=1)
        for run in group:
            ok = np.isfinite(run.train_return)
            axes[1].plot(run.train_steps[ok], run.train_return[ok], color=color, alpha=0.6,
                         linewidth=0.8)  # fmt: skip
            ok = np.isfinite(run.r_max)
            axes[1].plot(run.train_steps[ok], run.r_max[ok], color=color, linestyle="--",
                         linewidth=1)  # fmt: skip
        finals.setdefault(group[0].task, []).append((label, mean[-1], std[-1]))
    if reference:
        warnings += _draw_references(axes[0], tasks, runs)
    for task in tasks:
        bar = spec(task).success_bar
        if bar is not None:
            axes[0].axhline(bar, color="k", linestyle="--", linewidth=1)
    axes[0].set(xlabel="env steps", ylabel="eval return",
                title="eval return (mean ± std over seeds); -- success bar, : random")
    axes[0].legend(fontsize=7)
    axes[1].set(xlabel="env steps", ylabel="return",
                title="training-episode return (solid) and buffer R_max (dashed)")
    if panels == 3:
        labels, scores, errs = [], [], []
        for task in tasks:
            bar = spec(task).success_bar
            for label, m, s in finals[task]:
                if bar:
                    labels.append(label)
                    scores.append(m / bar)
                    errs.append(s / abs(bar))
        axes[2].bar(range(len(scores)), scores, yerr=errs, color="C0")
        axes[2].set_xticks(range(len(scores)), labels, rotation=60, ha="right", fontsize=6)
        axes[2].axhline(1.0, color="k", linestyle="--", linewidth=1)
        axes[2].set(ylabel="final eval return / success bar", title="normalised score")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    for line in warnings:
        print(line)
    return warnings
