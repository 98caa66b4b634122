"""The `eval` command's body: every checkpoint of a run evaluated, tabled and appended to CSV."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import jax

from sirl_jax.run import progress as prog
from sirl_jax.run import runlog
from sirl_jax.run.checkpoint import Checkpointer, CheckpointError
from sirl_jax.run.errors import UsageError
from sirl_jax.run.runner import build, eval_key
from sirl_jax.run.states import restore_state

_RANDOM_STREAM = 0x72616E64  # the random-policy baseline's evaluation key


def _eval_table(rows: list[dict], has_planner: bool) -> str:
    cols = (["planner", "policy"] if has_planner else ["policy"])
    head = f"{'env step':>10}" + "".join(
        f" | {c + ' return':>18} {'len':>6} {'succ':>5}" for c in cols)  # fmt: skip
    lines = [head, "-" * len(head)]
    for r in rows:
        line = f"{r['env_steps']:>10,}"
        for c in cols:
            ret = f"{r[f'eval/{c}_return']:.1f} ± {r[f'eval/{c}_return_std']:.1f}"
            line += (f" | {ret:>18} {r[f'eval/{c}_length']:>6.0f} "
                     f"{r[f'eval/{c}_success']:>5.2f}")  # fmt: skip
        lines.append(line)
    return "\n".join(lines)


def eval_run(run_dir: Path, step: int | None, episodes: int) -> list[dict]:
    """The body of `eval`: evaluate every checkpoint of a run (or `step`), planner and policy
    prior in eval mode, `episodes` episodes each in one jitted call, plus the uniform random
    policy once. Appends rows to RUN_DIR/eval/checkpoints.csv (and random.csv), prints a table.

    A damaged checkpoint is skipped with a note when evaluating all of them, and is an error
    (CheckpointError, naming the file) when it is the `step` asked for or the only one.
    """
    from sirl_jax.evaluate import make_random_evaluate
    from sirl_jax.run.compile_cache import enable_compilation_cache

    enable_compilation_cache()
    if not run_dir.is_dir():
        raise UsageError(f"run directory {run_dir} does not exist")
    config = runlog.load_config(run_dir)
    try:
        config = dataclasses.replace(
            config, train=dataclasses.replace(config.train, eval_episodes=episodes))
    except ValueError as e:
        raise UsageError(str(e)) from e
    if not (run_dir / "checkpoints").is_dir():
        raise UsageError(f"{run_dir} has no checkpoints/ (the run saved none yet)")
    spec, train = build(config)
    ckpt = Checkpointer(run_dir / "checkpoints")
    available = ckpt.steps()
    if not available:
        raise UsageError(f"{run_dir} has no complete checkpoint yet")
    if step is not None and step not in available:
        raise UsageError(f"--step {step}: no checkpoint at that env step; available: {available}")
    steps = [step] if step is not None else available
    evaluate = jax.jit(train.evaluate)
    key = jax.random.PRNGKey(config.train.seed)
    out_dir = run_dir / "eval"
    out_dir.mkdir(exist_ok=True)
    table = runlog.CsvLog(out_dir / "checkpoints.csv")
    rows, skipped = [], []
    try:
        for s in steps:
            try:
                state, _ = restore_state(ckpt, train.init, key, s)
            except CheckpointError as e:
                if len(steps) == 1:
                    raise
                skipped.append(s)
                print(f"skipped env step {s:,}: {e}", file=sys.stderr)
                continue
            metrics = prog.host_scalars(jax.device_get(evaluate(state, eval_key(
                config.train.seed, s))))  # fmt: skip
            row = {"env_steps": s, "episodes": episodes, "task": spec.id, **metrics}
            table.append(row)
            rows.append(row)
    finally:
        ckpt.close()
    random_metrics = prog.host_scalars(jax.device_get(jax.jit(
        make_random_evaluate(train.env, episodes))(jax.random.fold_in(
        jax.random.PRNGKey(config.train.seed), _RANDOM_STREAM))))  # fmt: skip
    runlog.CsvLog(out_dir / "random.csv").append(
        {"env_steps": 0, "episodes": episodes, "task": spec.id, **random_metrics})
    print(_eval_table(rows, config.agent.plans))
    print(f"random policy: return {random_metrics['eval/random_return']:.1f} ± "
          f"{random_metrics['eval/random_return_std']:.1f}, length "
          f"{random_metrics['eval/random_length']:.0f}; rows appended to {out_dir}")  # fmt: skip
    if skipped:
        raise CheckpointError(f"{len(skipped)} damaged checkpoint(s) skipped: {skipped}; the "
                              f"other {len(rows)} were evaluated")  # fmt: skip
    return rows
