"""The 31 tasks in one table: contact agreement with HumanoidBench by class, reward agreement in
exact mode, and speed share of the bare robot; then every contact miss with what measured it.

Reads what two harnesses wrote, measures nothing itself:

- `hb_parity --out` (docs/results/hb_parity.json): per task, contact agreement per class and
  the reward's |d| (all stages; the worst stage's p95 is the one shown), plus, for the states
  where only one side touches, how deep that side's contact is and how far apart our colliders
  are (`OurGap`).
- `bench_tasks --out` (E = 64, every task against the bare robot, side by side): the speed
  share (`ratio`) of each task at its default contact set, hand_floor and budget; given several
  files, a task's row in a later one replaces an earlier one's.
- `pair_cap --out` (docs/results/pair_cap.json): the share of states in which MJX's cull
  (`max_geom_pairs`) drops a pair that touches, in its worst collision group. hb_parity's
  contacts are MuJoCo C's on our model; this is what MJX, which trains, loses on top.

    .venv/bin/python -m experiments.fidelity.task_table \\
        --parity docs/results/hb_parity.json --bench docs/benchmarks/bench_tasks_all.json \
        --pair-cap docs/results/pair_cap.json

Bars (issue 29): contact agreement >= 99% in the classes robot-fixture / robot-obstacle,
hand-object and object-object; reward median |d| <= 0.005 and p95 <= 0.02 on every stage;
speed share >= 0.30. Robot-floor is shown but has no bar.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from sirl_jax.envs.tasks import LOCOMOTION, MANIPULATION, task_id

BAR_AGREEMENT, BAR_MEDIAN, BAR_P95, BAR_SPEED = 0.99, 0.005, 0.02, 0.30
STATIC = ("robot-fixture", "robot-obstacle")
BAR_COLUMNS = ("hand-object", "object-object")
LEVERS = {"max_contact_points", "max_geom_pairs", "prism_sides"}
"""Keys of a `bench_tasks` row measuring a lever, not the task's default."""


def task_rows() -> list[tuple[str, str]]:
    """(short name, id) of the 31 tasks: locomotion (on h1hand), then manipulation."""
    return [(r.name, task_id("h1hand", r.name)) for r in LOCOMOTION] + [
        (r.name, task_id(r.robot, r.name)) for r in MANIPULATION
    ]


def _pct(c: dict | None) -> str:
    if not c or c.get("agreement") is None:
        return "-"
    pct = f"{100 * c['agreement']:.1f}"
    return f"**{pct}**" if c["bar"] and c["agreement"] < BAR_AGREEMENT else pct


def _static(contacts: dict) -> dict | None:
    return next((contacts[k] for k in STATIC if k in contacts), None)


def reward_worst(row: dict) -> tuple[float, float]:
    """(median, p95) |d| of the task's reward: the worst over the reset task state and every
    forced stage."""
    parts = [row["reward"], *row.get("stages", {}).values()]
    return max(p["median"] for p in parts), max(p["p95"] for p in parts)


def speed(*benches: dict) -> dict[str, float]:
    """{task: ratio} of each task's default row (contact set hb, hand_floor all, no lever); a
    task's row in a later bench replaces an earlier bench's."""
    out = {}
    for bench in benches:
        first = {}
        for r in bench["rows"]:
            if r.get("task") and not LEVERS & set(r):
                first.setdefault(r["task"], r["ratio"])
        out.update(first)
    return out


def cull(pair_cap: dict) -> dict[str, str]:
    """{task id: "x.x" (% of states where MJX drops a touching pair, worst group)}."""
    out = {}
    for tid, v in pair_cap.items():
        worst = max((g["dropped_states"] for g in v["groups"].values()), default=0.0)
        out[tid] = f"{100 * worst:.1f}"
    return out


def misses(row: dict) -> list[tuple[str, dict]]:
    """(class, entry) of every bar class under 99%."""
    return [
        (k, v)
        for k, v in row["contacts"].items()
        if v["bar"] and v["agreement"] is not None and v["agreement"] < BAR_AGREEMENT
    ]


def main_table(parity: dict, ratios: dict[str, float], drops: dict[str, str]) -> list[str]:
    lines = [
        "| task | robot-fixture / obstacle | hand-object | object-object | robot-floor (no bar) "
        "| reward median / p95 \\|d\\| | speed share | MJX cull drops (% states) | bars |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for short, tid in task_rows():
        row = parity.get(tid)
        ratio = ratios.get(short)
        share = "-" if ratio is None else (f"**{ratio:.2f}**" if ratio < BAR_SPEED else
                                           f"{ratio:.2f}")  # fmt: skip
        if row is None or "error" in row:
            lines.append(f"| {short} | not measured | | | | | {share} | {drops.get(tid, '-')} | |")
            continue
        c = row["contacts"]
        med, p95 = reward_worst(row)
        failed = [k for k, _ in misses(row)]
        if med > BAR_MEDIAN or p95 > BAR_P95:
            failed.append("reward")
        if ratio is not None and ratio < BAR_SPEED:
            failed.append("speed")
        lines.append(
            f"| {short} | {_pct(_static(c))} | {_pct(c.get('hand-object'))} | "
            f"{_pct(c.get('object-object'))} | {_pct(c.get('robot-floor'))} | "
            f"{med:.1g} / {p95:.1g} | {share} | {drops.get(tid, '-')} | "
            f"{', '.join(failed) or 'all met'} |"
        )
    return lines


def _span(d: dict) -> str:
    return f"{d['p50']:g} / {d['max']:g}" if d else "-"


def miss_table(parity: dict) -> list[str]:
    lines = [
        "| task | class | agreement | ours only: states, depth p50 / max mm | HumanoidBench "
        "only: states, its depth p50 / max mm | there, our gap p50 / max mm; pair left out "
        "| most frequent pairs (ours only; HumanoidBench only) |",
        "|---|---|---:|---|---|---|---|",
    ]
    for short, tid in task_rows():
        row = parity.get(tid)
        if row is None or "error" in row:
            continue
        for cls, v in misses(row):
            n_ours, n_hb = v.get("ours_only_states", "-"), v.get("hb_only_states", "-")
            pairs = "; ".join(
                ", ".join(v.get(k, [])[:2]) or "-" for k in ("ours_only_pairs", "hb_only_pairs")
            ).replace("|", "\\|")  # a pair's label is "geom|geom"; escaped in a table cell
            lines.append(
                f"| {short} | {cls} | {100 * v['agreement']:.1f}% | {n_ours}, "
                f"{_span(v.get('ours_only_depth_mm', {}))} | {n_hb}, "
                f"{_span(v.get('hb_only_depth_mm', {}))} | "
                f"{_span(v.get('hb_only_our_gap_mm', {}))}; {v.get('hb_only_no_pair', '-')} "
                f"| {pairs} |"
            )
    return lines


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--parity", type=Path, default=Path("docs/results/hb_parity.json"))
    p.add_argument("--bench", type=Path, nargs="+", required=True,
                   help="bench_tasks --out JSON files; a task's row in a later file replaces "
                   "an earlier one's (a rerun of some tasks over a run of all)")  # fmt: skip
    p.add_argument("--pair-cap", type=Path, default=Path("docs/results/pair_cap.json"))
    args = p.parse_args(argv)
    parity = json.loads(args.parity.read_text())
    benches = [json.loads(b.read_text()) for b in args.bench]
    ratios = speed(*benches)
    runs = "; ".join(f"{b.name}, E = {bench['num_envs']}, {bench['rounds']} x {bench['calls']} "
                     f"calls" for b, bench in zip(args.bench, benches, strict=True))  # fmt: skip
    print(f"<!-- hb_parity: {args.parity.name}; bench_tasks: {runs} -->")
    drops = cull(json.loads(args.pair_cap.read_text())) if args.pair_cap.exists() else {}
    print("\n".join(main_table(parity, ratios, drops)))
    print()
    print("\n".join(miss_table(parity)))


if __name__ == "__main__":
    main()
