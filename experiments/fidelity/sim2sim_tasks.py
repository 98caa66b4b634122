"""The sim-to-sim gap per task: `sim2sim --task NAME --policy random` over HumanoidBench's tasks.

For each task, `--episodes` episodes of one seeded uniform-random action sequence each, from the
same initial states (drawn by the contract's reset rule), in CPU MuJoCo driven through the
task's contract alone and in the task's MJX env. Both returns are the task's own reward (the CPU
side scored on its recorded states, `sirl_jax.run.sim2sim`). Per task it records the mean
returns and lengths, the mean |return gap|, the first-step observation difference, the step at
which the two observation sequences part, and whether the contract's termination ended the CPU
loop where the task's rule does. A task whose contract cannot describe its reset or
observation is recorded with the reason (the manipulation tasks whose objects are placed by
task code).

    .venv/bin/python -m experiments.fidelity.sim2sim_tasks [--tasks stand,reach] [--episodes 5]
        [--max-steps 300] [--seed 0] [--out docs/results/sim2sim_tasks.json]

Rows are written to `--out` after each task, and a rerun skips the tasks already there, so an
interrupted run resumes. Random actions make the robot fall within ~50 steps on most tasks, so
these figures measure how soon the two simulators part and how far the returns of the same
open-loop action sequence differ, not a trained controller's robustness.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from sirl_jax.envs.tasks import LOCOMOTION, MANIPULATION, task_id
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.contract_sim import ContractError
from sirl_jax.run.errors import UsageError
from sirl_jax.run.sim2sim import sim2sim


def row(task: str, episodes: int, max_steps: int, seed: int) -> dict:
    t0 = time.perf_counter()
    try:
        r = sim2sim(None, episodes, "random", max_steps, seed, task=task)
    except (ContractError, UsageError) as e:
        return {"task": task, "refused": str(e)}
    eps = r["episodes"]
    parted = [e["parted_at"] for e in eps]
    return {
        "task": r["task"],
        "episodes": len(eps),
        "max_steps": max_steps,
        "cpu_return": r["mean_cpu_return"],
        "mjx_return": r["mean_mjx_return"],
        "mean_abs_return_gap": r.get("mean_abs_return_gap"),
        "cpu_length": r["mean_cpu_length"],
        "mjx_length": r["mean_mjx_length"],
        "first_step_obs_diff": [e["first_step_obs_diff"] for e in eps],
        "parted_at": parted,
        "termination_agreement": r.get("termination_agreement"),
        "cpu_return_source": r["cpu_return_source"],
        "seconds": round(time.perf_counter() - t0, 1),
    }


def table(rows: list[dict]) -> str:
    def f(x, spec=".2f"):
        return "n/a" if x is None else format(x, spec)

    lines = [
        "| task | return CPU / MJX | mean \\|gap\\| | length CPU / MJX | obs diff after step 1 "
        "(median) | parted at (median step) | termination agrees |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        if "refused" in r:
            lines.append(f"| {r['task']} | not described: {r['refused']} | | | | | |")
            continue
        parted = [p for p in r["parted_at"] if p is not None]
        part = f"{np.median(parted):.0f} ({len(parted)}/{r['episodes']})" if parted else "never"
        agree = r["termination_agreement"]
        lines.append(
            f"| {r['task']} | {f(r['cpu_return'])} / {f(r['mjx_return'])} | "
            f"{f(r['mean_abs_return_gap'])} | {f(r['cpu_length'], '.1f')} / "
            f"{f(r['mjx_length'], '.1f')} | {np.median(r['first_step_obs_diff']):.1e} | {part} | "
            f"{'n/a' if agree is None else f'{100 * agree:.0f}%'} |"
        )
    return "\n".join(lines)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ids = {r.name: task_id("h1hand", r.name) for r in LOCOMOTION}
    ids |= {r.name: task_id(r.robot, r.name) for r in MANIPULATION}
    every = list(ids)
    p.add_argument("--tasks", default=",".join(every))
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--max-steps", type=int, default=300)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    enable_compilation_cache()
    rows = json.loads(args.out.read_text()) if args.out and args.out.exists() else []
    done = {r["name"] for r in rows}
    for name in args.tasks.split(","):
        if name not in every:
            raise SystemExit(f"error: unknown task {name!r}; allowed: {', '.join(every)}")
        if name in done:
            continue
        r = {"name": name, **row(ids[name], args.episodes, args.max_steps, args.seed)}
        rows.append(r)
        print(json.dumps(r), flush=True)
        if args.out:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            tmp = args.out.with_suffix(".tmp")
            tmp.write_text(json.dumps(rows, indent=1) + "\n")
            tmp.replace(args.out)
    print("\n" + table(rows))


if __name__ == "__main__":
    main()
