"""`report RUN`: what a run did, as one self-contained HTML page that opens offline.

Everything is read from the run directory, nothing is recomputed: config.json (the config),
versions.json (starts, commit, device), metrics.jsonl (R_max, blow-ups, Warp buffer overflows,
non-finite counters, wall time), the evaluations (eval/checkpoints.csv from `eval` when
present, else eval.jsonl from training), checkpoints/ (the steps saved) and the newest *.mp4
anywhere under the run directory (`render RUN` writes RUN/videos/). The curves are `plot`'s
PNG with the published reference overlay (`plot --reference`). Styles are inline, the PNG
and the video are base64 data URIs, so the file can be mailed or archived alone.

The page's facts are gathered by `gather` (a `Report` of plain values, testable without HTML)
and written by `report_html.to_html`.
"""

from __future__ import annotations

import contextlib
import io
import math
import tempfile
from pathlib import Path

from sirl_jax.run import runlog
from sirl_jax.run.errors import UsageError
from sirl_jax.run.progress import format_duration
from sirl_jax.run.report_data import POLICIES, VIDEO_LIMIT, Report, data_uri
from sirl_jax.run.report_html import to_html

NEEDS = ("report needs a run directory written by `train`: config.json, metrics.jsonl and "
         "at least one complete checkpoint in checkpoints/")  # fmt: skip
def checkpoint_steps(run_dir: Path) -> list[int]:
    """Env steps of the run's complete checkpoints, ascending (`checkpoint.complete_steps`)."""
    from sirl_jax.run.checkpoint_files import complete_steps


    return complete_steps(run_dir / "checkpoints")


def best_checkpoint(run_dir: Path) -> dict | None:
    """The checkpoint the run marked best at evaluation (`checkpoint_files.read_best`)."""
    from sirl_jax.run.checkpoint_files import read_best

    return read_best(run_dir / "checkpoints")


def _number(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def check_run(run_dir: Path) -> tuple[list[dict], list[int]]:
    """(metrics rows, checkpoint steps) of a run; one-line UsageError naming what is missing."""
    if not run_dir.is_dir():
        raise UsageError(f"run directory {run_dir} does not exist; {NEEDS}")
    if not (run_dir / "config.json").is_file():
        raise UsageError(f"{run_dir} has no config.json; {NEEDS}")
    path = run_dir / "metrics.jsonl"
    metrics = runlog.read_jsonl(path) if path.is_file() else []
    if not metrics:
        raise UsageError(f"{run_dir} has no training logs (metrics.jsonl is missing or "
                         f"empty); {NEEDS}")  # fmt: skip
    steps = checkpoint_steps(run_dir)
    if not steps:
        raise UsageError(f"{run_dir} has no complete checkpoint; {NEEDS}")
    return metrics, steps


def eval_rows(run_dir: Path) -> tuple[list[dict], str]:
    """(rows, where they came from): `eval`'s table if any, else the training-time evals; the
    last row of each env step wins (a re-run of `eval` appends)."""
    rows = runlog.CsvLog(run_dir / "eval" / "checkpoints.csv").rows()
    source = "`eval` (eval/checkpoints.csv)"
    if not rows:
        path = run_dir / "eval.jsonl"
        rows = runlog.read_jsonl(path) if path.is_file() else []
        source = "training (eval.jsonl)"
    by_step = {}
    for row in rows:
        by_step[int(_number(row["env_steps"]))] = {k: (v if k == "task" else _number(v))
                                                   for k, v in row.items()}  # fmt: skip
    return [by_step[s] for s in sorted(by_step)], source


def run_counters(metrics: list[dict], evals: list[dict]) -> dict[str, float]:
    """Totals over the run: env blow-ups (training), eval episodes cut by a blow-up, logged
    periods with a physics overflow (a Warp buffer, or MJX-JAX's contact budget, full; and the
    largest per-step rate), non-finite counts."""
    def total(key, rows):
        return float(sum(v for r in rows if math.isfinite(v := _number(r.get(key)))))

    out = {"env blow-ups (training steps reset)": total("env/blowups", metrics)}
    for prefix, _ in POLICIES:
        if any(f"eval/{prefix}_blowups" in r for r in evals):
            out[f"eval episodes cut by a blow-up ({prefix})"] = total(f"eval/{prefix}_blowups",
                                                                      evals)  # fmt: skip
    overflow = [_number(r.get("env/physics_overflow")) for r in metrics
                if "env/physics_overflow" in r]  # fmt: skip
    if overflow:
        out["logged periods with a physics overflow (Warp buffer or contact budget)"] = float(
            sum(1 for v in overflow if v > 0))  # fmt: skip
        out["largest overflow rate (fraction of steps)"] = max(overflow)
    for key in sorted({k for r in metrics for k in r if k.startswith("nonfinite")}):
        out[key] = total(key, metrics)
    return out


def wall_seconds(metrics: list[dict]) -> float:
    """Wall time summed over a run's (re)starts: `wall_time` restarts from 0 in each process,
    so each segment's last value counts once."""
    wall, last = 0.0, 0.0
    for row in metrics:
        t = _number(row.get("wall_time"))
        if t < last:
            wall += last
        last = t if math.isfinite(t) else last
    return wall + last


def cost_text(metrics: list[dict], starts: list[dict]) -> str:
    """The measured cost: wall time summed over the run's (re)starts (`wall_seconds`), env
    steps per second, and the device."""
    wall = wall_seconds(metrics)
    steps = int(metrics[-1]["env_steps"])
    device = starts[-1].get("devices", ["?"])[0] if starts else "unknown device"
    rate = f", {steps / wall:,.1f} env steps/s" if wall > 0 else ""
    return (f"{steps:,} env steps in {format_duration(wall)} of wall time over "
            f"{max(len(starts), 1)} start(s){rate}, on {device} (measured from metrics.jsonl; "
            "compilation included)")


def training_videos(run_dir: Path) -> list[Path]:
    """The videos `--train.video-every` wrote, by env step."""
    return sorted((run_dir / "videos").glob("step_*.mp4"))


def latest_video(run_dir: Path) -> Path | None:
    """The newest .mp4 under the run directory that is not a training video, or None."""
    training = set(training_videos(run_dir))
    videos = [p for p in run_dir.rglob("*.mp4") if p.is_file() and p not in training]
    return max(videos, key=lambda p: p.stat().st_mtime) if videos else None


def _curves(run_dir: Path) -> tuple[bytes | None, list[str]]:
    """`plot --reference` of this run as PNG bytes, and the lines it printed or refused with."""
    from sirl_jax.run.plot import plot

    printed = io.StringIO()
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(printed):
        out = Path(tmp) / "curves.png"
        try:
            plot([run_dir], out, reference=True)
        except UsageError as e:
            return None, [f"no curves: {e}"]
        png = out.read_bytes()
    return png, [ln for ln in printed.getvalue().splitlines() if ln.strip()]


def task_line(task: str) -> str:
    """`pendulum-swingup-v0 · T=250 · success bar 150` (the registry's spec; nothing built)."""
    from sirl_jax.envs import spec

    try:
        s = spec(task)
    except (KeyError, ImportError, ValueError):
        return task
    bar = "no success bar" if s.success_bar is None else f"success bar {s.success_bar:g}"
    return f"{s.id} · T={s.episode_length} · {bar}"


def gather(run_dir: Path, curves: bool = True) -> Report:
    """The facts of `run_dir` (UsageError in one line when it is not a finished-enough run)."""
    import json

    from sirl_jax.config import flatten_config

    if runlog.sweep_runs(run_dir):  # one line naming the sweep's runs
        try:
            runlog.load_config(run_dir)
        except runlog.RunDirError as e:
            raise UsageError(str(e)) from e
    metrics, steps = check_run(run_dir)
    try:
        config = runlog.load_config(run_dir)
    except runlog.RunDirError as e:
        raise UsageError(f"{e}; {NEEDS}") from e
    evals, source = eval_rows(run_dir)
    random_rows = runlog.CsvLog(run_dir / "eval" / "random.csv").rows()
    versions = run_dir / "versions.json"
    starts = json.loads(versions.read_text()) if versions.is_file() else []
    r_max = [v for r in metrics if math.isfinite(v := _number(r.get("r_max")))]
    report = Report(
        run_dir=run_dir, task=config.train.task, seed=config.train.seed,
        task_line=task_line(config.train.task),
        config=flatten_config(config), checkpoints=steps,
        env_steps=int(metrics[-1]["env_steps"]), eval_source=source, eval_rows=evals,
        random_return=_number(random_rows[-1]["eval/random_return"]) if random_rows else None,
        r_max_last=r_max[-1] if r_max else math.nan, r_max_best=max(r_max, default=math.nan),
        counters=run_counters(metrics, evals), cost=cost_text(metrics, starts), starts=starts,
        video=latest_video(run_dir), videos=training_videos(run_dir),
        best=best_checkpoint(run_dir),
    )  # fmt: skip
    if not evals:
        report.notes.append(f"no evaluations yet: run `python -m sirl_jax eval {run_dir}`")
    elif curves:
        report.plot_png, notes = _curves(run_dir)
        report.notes += notes
    return report


def write_report(run_dir: Path, out: Path | None = None) -> Path:
    """Writes the page (default RUN_DIR/report.html); returns its path."""
    report = gather(run_dir)
    out = out or run_dir / "report.html"
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(to_html(report), encoding="utf-8")
    tmp.replace(out)
    return out


__all__ = ["NEEDS", "POLICIES", "VIDEO_LIMIT", "Report", "check_run", "checkpoint_steps",
           "cost_text", "data_uri", "eval_rows", "gather", "latest_video", "run_counters",
           "task_line", "wall_seconds",
           "write_report"]  # fmt: skip
