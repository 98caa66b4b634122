"""`report SWEEP_DIR`: a sweep's page, each point of the grid (an arm) as mean ± std over its
seeds, beside every run's own figures.

Read from the sweep directory alone, as `report` reads a run: sweep.json (the axes, the seeds,
the runs in the program's order) and each run's directory (`report.gather`, no curves). Per
arm: the final evaluation's return, the mean of each run's last three evaluations, the best
evaluation, and the runs that reached the task's success bar and at which env step. The cost
is the program's: the runs share one wall clock, so a run costs the wall time over R. The
curves are `plot SWEEP_DIR --reference` (each arm mean ± std over its seeds). A run's own page
is `report SWEEP_DIR/<run>`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sirl_jax.run import runlog
from sirl_jax.run.errors import UsageError
from sirl_jax.run.progress import format_duration
from sirl_jax.run.report import Report, _curves, gather, task_line, wall_seconds
from sirl_jax.run.report_html import _card, _e, _num, page


@dataclass
class RunRow:
    """One run of the sweep, as its arm's table shows it."""

    name: str
    seed: int
    env_steps: int
    final: float  # the last evaluation's return
    last3: float  # the mean of the last three evaluations' returns
    best: float
    best_step: int
    first_at_bar: int | None  # the first evaluated env step at or over the success bar
    blowups: float


@dataclass
class SweepReport:
    run_dir: Path
    task: str
    task_line: str
    success_bar: float | None
    axes: dict  # field -> values
    seeds: int
    which: str  # "planner" or "policy": the return the arms are compared on
    arms: dict[str, list[RunRow]]  # point label -> its runs, seeds in order
    cost: str
    plot_png: bytes | None = None
    notes: list[str] = field(default_factory=list)


def _row(name: str, r: Report, which: str, bar: float | None) -> RunRow:
    if not r.eval_rows:
        raise UsageError(f"{r.run_dir} has no evaluations yet; the sweep's page needs every "
                         f"run's (run `python -m sirl_jax eval {r.run_dir}`)")  # fmt: skip
    steps = [int(x["env_steps"]) for x in r.eval_rows]
    ret = [float(x.get(f"eval/{which}_return", math.nan)) for x in r.eval_rows]
    at_bar = [s for s, v in zip(steps, ret, strict=True) if bar is not None and v >= bar]
    best = int(np.nanargmax(ret)) if np.isfinite(ret).any() else 0
    return RunRow(name=name, seed=r.seed, env_steps=r.env_steps, final=ret[-1],
                  last3=float(np.mean(ret[-3:])), best=ret[best], best_step=steps[best],
                  first_at_bar=at_bar[0] if at_bar else None,
                  blowups=sum(v for k, v in r.counters.items() if "blow-up" in k))  # fmt: skip


def gather_sweep(run_dir: Path, curves: bool = True) -> SweepReport:
    """The facts of a sweep directory (UsageError in one line when a run is not readable)."""
    from sirl_jax.envs import spec

    path = run_dir / "sweep.json"
    if not path.is_file():
        raise UsageError(f"{run_dir} has no sweep.json: not a sweep directory")
    sweep = json.loads(path.read_text())
    names, seeds = sweep["runs"], int(sweep["seeds"])
    reports = {n: gather(run_dir / n, curves=False) for n in names}
    first = reports[names[0]]
    which = "planner" if any("eval/planner_return" in x for x in first.eval_rows) else "policy"
    try:
        bar = spec(first.task).success_bar
    except (KeyError, ImportError, ValueError):
        bar = None
    arms: dict[str, list[RunRow]] = {}
    for n in names:  # seeds innermost (`Sweep.runs`); an arm is a name less its seed
        label = n.rsplit("_seed=", 1)[0] if n.count("_seed=") else "seeds"
        arms.setdefault(label, []).append(_row(n, reports[n], which, bar))
    metrics = runlog.read_jsonl(run_dir / names[0] / "metrics.jsonl")
    wall, steps = wall_seconds(metrics), int(metrics[-1]["env_steps"])
    cost = (f"{len(names)} runs in one program: {steps:,} env steps per run in "
            f"{format_duration(wall)} of wall time, {format_duration(wall / len(names))} per "
            f"run ({steps * len(names) / wall:,.1f} env steps/s over the runs); "
            f"on {first.cost.split(' on ', 1)[-1]}" if wall > 0 else first.cost)  # fmt: skip
    report = SweepReport(run_dir=run_dir, task=first.task, task_line=task_line(first.task),
                         success_bar=bar, axes=sweep["axes"], seeds=seeds, which=which,
                         arms=arms, cost=cost)  # fmt: skip
    if curves:
        report.plot_png, report.notes = _curves(run_dir)
    return report


def _stat(values: list[float]) -> str:
    v = np.asarray(values, float)
    return f"{_num(float(np.mean(v)))} ± {_num(float(np.std(v)))}"


def _arm_table(r: SweepReport) -> str:
    head = ("<tr><th class=l>arm</th><th>seeds</th><th>final</th><th>last 3</th><th>best</th>"
            "<th>at the bar</th><th>blow-ups</th></tr>")  # fmt: skip
    body = []
    for label, rows in r.arms.items():
        hit = [x.first_at_bar for x in rows if x.first_at_bar is not None]
        bar = ("–" if r.success_bar is None else f"{len(hit)} of {len(rows)}"
               + (f", first @ {min(hit):,}" if hit else ""))  # fmt: skip
        cells = [str(len(rows)), _stat([x.final for x in rows]), _stat([x.last3 for x in rows]),
                 _stat([x.best for x in rows]), bar, f"{sum(x.blowups for x in rows):g}"]
        body.append(f"<tr><td class=l>{_e(label)}</td>"
                    + "".join(f"<td>{_e(c)}</td>" for c in cells) + "</tr>")  # fmt: skip
    return f"<table>{head}{''.join(body)}</table>"


def _run_table(r: SweepReport) -> str:
    head = ("<tr><th class=l>run</th><th>seed</th><th>env steps</th><th>final</th>"
            "<th>last 3</th><th>best (env step)</th><th>first at the bar</th></tr>")
    body = []
    for rows in r.arms.values():
        for x in rows:
            cells = [str(x.seed), f"{x.env_steps:,}", _num(x.final), _num(x.last3),
                     f"{_num(x.best)} ({x.best_step:,})",
                     "–" if x.first_at_bar is None else f"{x.first_at_bar:,}"]
            body.append(f"<tr><td class=l><code>{_e(x.name)}</code></td>"
                        + "".join(f"<td>{_e(c)}</td>" for c in cells) + "</tr>")  # fmt: skip
    return f"<table>{head}{''.join(body)}</table>"


def sweep_html(r: SweepReport) -> str:
    """The page of a sweep, as one string (styles inline, the curves a data URI)."""
    from sirl_jax.run.report_data import data_uri

    axes = ", ".join(f"{f} = {', '.join(f'{v:g}' for v in vs)}" for f, vs in r.axes.items())
    runs = sum(len(x) for x in r.arms.values())
    bar = "" if r.success_bar is None else f"; the success bar is {r.success_bar:g}"
    cards = [_card(str(runs), "runs in one program"), _card(str(len(r.arms)), "arms"),
             _card(str(r.seeds), "seeds per arm")]  # fmt: skip
    curves = ("" if r.plot_png is None else
              f'<img alt="curves" src="{data_uri("image/png", r.plot_png)}">')  # fmt: skip
    notes = "".join(f"<div class=note>{_e(n)}</div>" for n in r.notes)
    title = f"{r.task}: sweep {r.run_dir.name}"
    return page(title, f"""<h1>{_e(r.task)} · sweep of {runs} runs</h1>
<p class=sub>{_e(r.task_line)} · {_e(axes or "seeds only")} · sirl_jax sweep report</p>
<div class="cards">{"".join(cards)}</div>
<h2>Arms (mean ± std over seeds)</h2>
<p class=sub>{_e(r.which)} eval return: the final evaluation, the mean of each run's last three,
the best evaluation{_e(bar)}.</p>{_arm_table(r)}
<h2>Runs</h2><p class=sub>Each run's own page: <code>python -m sirl_jax report
{_e(r.run_dir)}/&lt;run&gt;</code>.</p>{_run_table(r)}
<h2>Cost</h2><p>{_e(r.cost)}</p>
<h2>Curves</h2>{curves}{notes}
""")


def write_sweep_report(run_dir: Path, out: Path | None = None) -> Path:
    """Writes the sweep's page (default SWEEP_DIR/report.html); returns its path."""
    page = sweep_html(gather_sweep(run_dir))
    out = out or run_dir / "report.html"
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(out)
    return out
