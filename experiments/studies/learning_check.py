"""Does a CPU-sized config learn? Trains one seed and writes the return curve (CSV + PNG).

    .venv/bin/python -m experiments.studies.learning_check         # pendulum, `cpu` preset
    .venv/bin/python -m experiments.studies.learning_check --task dmc:CartpoleSwingup --steps 100000

Evaluates the planner and the policy prior (eval mode, `eval_episodes` episodes) every
`eval_every` env steps, and once before any training (the random-init agent). Writes
experiments/out/learning_<task>.csv (and .png when matplotlib is installed) and prints the
wall-clock. Not a test: nothing is asserted.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
from pathlib import Path

import jax
import numpy as np
import tyro

from experiments.paper.common import arm_env
from sirl_jax.presets import get_preset
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.train import make_train

OUT = Path(__file__).parents[1] / "out"  # experiments/out/


@dataclasses.dataclass(frozen=True)
class Args:
    preset: str = "cpu"
    """Config preset to start from."""
    task: str | None = None
    """Override the preset's task."""
    steps: int | None = None
    """Override the preset's total env steps."""
    seed: int = 0
    beta: float | None = None
    """Override the SIRL beta (0 = plain TD-MPC2)."""


def _row(env_steps, wall, train_return, ev) -> dict:
    return {
        "env_steps": int(env_steps),
        "wall_s": round(wall, 1),
        "train_return": round(float(train_return), 2),
        "eval_planner_return": round(float(ev.get("eval/planner_return", math.nan)), 2),
        "eval_policy_return": round(float(ev["eval/policy_return"]), 2),
        "eval_planner_success": float(ev.get("eval/planner_success", math.nan)),
        "r_max": round(float(ev["eval/r_max"]), 2),
    }


def _plot(rows: list[dict], path: Path, title: str) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    x = [r["env_steps"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, label in (
        ("eval_planner_return", "eval: planner"),
        ("eval_policy_return", "eval: policy prior"),
        ("train_return", "training episodes"),
        ("r_max", "R_max in buffer"),
    ):
        ax.plot(x, [r[key] for r in rows], marker=".", label=label)
    ax.set_xlabel("env steps")
    ax.set_ylabel("episode return")
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return True


def main(args: Args) -> None:
    enable_compilation_cache()
    cfg = get_preset(args.preset)
    train_over = {"seed": args.seed}
    if args.task is not None:
        train_over["task"] = args.task
    if args.steps is not None:
        train_over["steps"] = args.steps
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(cfg.train, **train_over))
    if args.beta is not None:
        sirl = dataclasses.replace(cfg.agent.sirl, beta=args.beta)
        cfg = dataclasses.replace(cfg, agent=dataclasses.replace(cfg.agent, sirl=sirl))
    tc = cfg.train
    env = arm_env(cfg)
    train = make_train(cfg, env)
    print(train.buffer.describe())
    print(f"seed_steps={train.seed_steps} pretrain_updates={train.pretrain_updates}")

    start = time.perf_counter()
    state = jax.jit(train.init)(jax.random.PRNGKey(tc.seed))
    step = jax.jit(train.step, donate_argnums=0)
    evaluate = jax.jit(train.evaluate)
    key_eval = jax.random.PRNGKey(tc.seed + 10_000)
    rows = [_row(0, 0.0, math.nan, jax.device_get(evaluate(state, key_eval)))]
    print(rows[-1])
    returns, next_eval = [], tc.eval_every
    num_calls = -(-tc.steps // tc.steps_per_call)
    for i in range(num_calls):
        state, metrics = step(state)
        metrics = jax.device_get(metrics)
        too_many = metrics["env/blowups"] > tc.max_blowup_rate * tc.steps_per_call
        if metrics["nonfinite_loss"] or too_many:
            raise FloatingPointError(f"non-finite values at chunk {i}: {metrics}")
        if metrics["episode/count"] > 0:
            returns.append(float(metrics["episode/return"]))
        env_steps = int(metrics["env_steps"])
        if env_steps >= next_eval or i == num_calls - 1:
            next_eval += tc.eval_every
            ev = jax.device_get(evaluate(state, jax.random.fold_in(key_eval, env_steps)))
            recent = np.mean(returns[-4:]) if returns else math.nan
            rows.append(_row(env_steps, time.perf_counter() - start, recent, ev))
            print(rows[-1], f"updates={int(metrics['updates'])}", flush=True)
    wall = time.perf_counter() - start

    OUT.mkdir(parents=True, exist_ok=True)
    stem = f"learning_{tc.task.replace(':', '_')}"
    with open(OUT / f"{stem}.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    title = f"{tc.task}, preset {args.preset}, beta {cfg.agent.sirl.beta}, seed {tc.seed}"
    plotted = _plot(rows, OUT / f"{stem}.png", title)
    print(f"wrote {OUT / stem}.csv{' and .png' if plotted else ''}; wall-clock {wall:.0f} s")


if __name__ == "__main__":
    main(tyro.cli(Args))
