"""The `sim2sim` report: the per-episode rows of both sides reduced to means (`summary`) and
printed as a table (`table`). The rows come from `sim2sim._sim2sim`."""

from __future__ import annotations

import numpy as np


def _mean(rows: list[dict], key: str) -> float | None:
    vals = [r[key] for r in rows if r.get(key) is not None]
    return float(np.mean(vals)) if vals and len(vals) == len(rows) else None


def summary(rows: list[dict], contract: dict, scored: bool) -> dict:
    """Means over the episodes (None unless every episode has the figure), the termination
    agreement, and why the return is missing when neither the task nor the contract scores it."""
    keys = ("cpu_return", "cpu_length", "mjx_return", "mjx_length", "return_gap",
            "first_step_obs_diff")  # fmt: skip
    out = {f"mean_{k}": _mean(rows, k) for k in keys}
    if out["mean_return_gap"] is not None:
        out["mean_abs_return_gap"] = float(np.mean([abs(r["return_gap"]) for r in rows]))
    if any("termination_agrees" in r for r in rows):
        out["termination_agreement"] = float(np.mean([r["termination_agrees"] for r in rows]))
    if not scored and contract["reward"]["kind"] == "not_described":
        out["return_note"] = f"return not computed: {contract['reward']['why']}"
    return out


def _fmt(x, spec: str = ".2f") -> str:
    return "n/a" if x is None else format(x, spec)


def table(rows: list[dict], summary: dict) -> str:
    """The printed report: one line per episode, then the means."""
    head = (f"{'ep':>3} | {'cpu return':>10} {'len':>5} | {'mjx return':>10} {'len':>5} | "
            f"{'gap':>8} | {'obs diff @1':>11} {'parted at':>9}")  # fmt: skip
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['episode']:>3} | {_fmt(r['cpu_return']):>10} {r['cpu_length']:>5} | "
            f"{_fmt(r.get('mjx_return')):>10} {r.get('mjx_length', '-'):>5} | "
            f"{_fmt(r.get('return_gap')):>8} | {_fmt(r.get('first_step_obs_diff'), '.2e'):>11} "
            f"{_fmt(r.get('parted_at'), 'd'):>9}")  # fmt: skip
    lines.append(f"mean: cpu {_fmt(summary['mean_cpu_return'])} (len "
                 f"{_fmt(summary['mean_cpu_length'], '.0f')}), mjx "
                 f"{_fmt(summary['mean_mjx_return'])} (len "
                 f"{_fmt(summary['mean_mjx_length'], '.0f')}), mean |gap| "
                 f"{_fmt(summary.get('mean_abs_return_gap'))}")  # fmt: skip
    if "termination_agreement" in summary:
        lines.append(
            f"the contract's termination ended the CPU loop where the task's rule does "
            f"in {100 * summary['termination_agreement']:.0f}% of episodes"
        )
    if "return_note" in summary:
        lines.append(summary["return_note"])
    return "\n".join(lines)
