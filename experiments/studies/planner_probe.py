"""The same networks under other planners: a study checkpoint evaluated at several MPPI sizes.

    .venv/bin/python -m experiments.studies.planner_probe --arm-dir RESULTS/study/tdmpc2 \
        [--step N] [--episodes 16] [--sizes 64x2:8:8 512x6:64:24] [--out probe.csv]

Is the study's small planner (64 samples x 2 iterations, 8 elites, 8 policy trajectories) what
holds its return back, or the world model and policy it plans with? This loads one checkpoint
of a study arm (`experiments.studies.sit_simple`: its config.json and vmapped train state) and
runs the study's own evaluation (planner and policy prior, eval mode, `--episodes` episodes per
seed, every seed vmapped) once per planner size, on the same networks and the same eval keys.
A size is `SAMPLESxITERATIONS:ELITES:PI_TRAJS`; TD-MPC2 adds 2 iterations for A >= 20 on top,
as in training. The reference planner is 512x6:64:24. Nothing is trained.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import jax
import numpy as np
import tyro

from experiments.paper.common import arm_env
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.runlog import CsvLog, RunDirError, load_config
from sirl_jax.train import make_train


@dataclasses.dataclass(frozen=True)
class Args:
    arm_dir: str
    """A study arm's directory (config.json, checkpoints/)."""
    step: int | None = None
    """The checkpoint's env step per seed (default: the latest)."""
    episodes: int = 16
    sizes: tuple[str, ...] = ("64x2:8:8", "512x6:64:24")
    out: str | None = None
    """Append one row per seed and size to this CSV."""


def parse_size(text: str) -> dict[str, int]:
    """'512x6:64:24' -> num_samples 512, iterations 6, num_elites 64, num_pi_trajs 24."""
    try:
        head, elites, pi = text.split(":")
        samples, iterations = head.split("x")
        size = dict(num_samples=int(samples), iterations=int(iterations),
                    num_elites=int(elites), num_pi_trajs=int(pi))  # fmt: skip
    except ValueError:
        raise SystemExit(f"error: size {text!r} is invalid; allowed: SAMPLESxITERATIONS:ELITES:"
                         "PI_TRAJS, e.g. 512x6:64:24") from None  # fmt: skip
    if (
        not 0 < size["num_elites"] <= size["num_samples"]
        or size["num_pi_trajs"] >= size["num_samples"]
    ):
        raise SystemExit(f"error: size {text!r}: need 0 < elites <= samples and pi_trajs < samples")
    return size


def main(args: Args) -> None:
    enable_compilation_cache()
    arm = Path(args.arm_dir)
    sizes = {s: parse_size(s) for s in args.sizes}
    try:
        base = load_config(arm)
    except RunDirError as e:
        raise SystemExit(f"error: --arm-dir: {e}") from None
    env = arm_env(base)
    if not (arm / "eval.csv").exists():
        raise SystemExit(f"error: {arm} has no eval.csv (the study arm's seeds are read from it)")
    seeds = len({r["seed"] for r in CsvLog(arm / "eval.csv").rows()})
    ckpt = Checkpointer(arm / "checkpoints")
    try:
        step = args.step if args.step is not None else ckpt.latest_step()
        if step is None:
            raise SystemExit(f"error: {arm / 'checkpoints'} holds no checkpoint")
        train0 = make_train(base, env)
        keys = jax.random.split(jax.random.PRNGKey(0), seeds)
        shape = jax.eval_shape(jax.vmap(train0.init), keys)
        state = ckpt.restore({"state": shape}, step)["state"]
    finally:
        ckpt.close()
    eval_keys = jax.random.split(jax.random.PRNGKey(7), seeds)
    rows = []
    print(f"{arm} at {step:,} env steps per seed, {seeds} seeds, {args.episodes} episodes each")
    for name, size in sizes.items():
        agent_cfg = dataclasses.replace(base.agent, **size)
        train_cfg = dataclasses.replace(base.train, eval_episodes=args.episodes)
        cfg = dataclasses.replace(base, agent=agent_cfg, train=train_cfg)
        train = make_train(cfg, env)
        t = time.perf_counter()
        m = jax.device_get(jax.jit(jax.vmap(train.evaluate))(state, eval_keys))
        secs = time.perf_counter() - t
        for s in range(seeds):
            rows.append({"arm_dir": arm.name, "env_steps": step, "size": name, "seed": s,
                         "episodes": args.episodes,
                         "planner_return": round(float(m["eval/planner_return"][s]), 3),
                         "planner_length": round(float(m["eval/planner_length"][s]), 1),
                         "policy_return": round(float(m["eval/policy_return"][s]), 3),
                         "policy_length": round(float(m["eval/policy_length"][s]), 1)})  # fmt: skip
        ret, length = m["eval/planner_return"], m["eval/planner_length"]
        print(f"  {name:>12}: planner {np.round(ret, 1)} (mean {np.mean(ret):.1f}, lengths "
              f"{np.round(length, 0)}), prior {np.round(m['eval/policy_return'], 1)}; "
              f"{secs:.0f} s with compile", flush=True)  # fmt: skip
    if args.out:
        CsvLog(Path(args.out)).extend(rows)


if __name__ == "__main__":
    main(tyro.cli(Args))
