"""Where a CPU hour of the sit_simple study goes: wall-clock per 1k env steps per seed, by part.

    .venv/bin/python -m experiments.bench.bench_study \
        --state results/sit_simple/study/tdmpbc [--repeats 5] [--out bench_study.json]

The study's program (`experiments.studies.sit_simple`, config `e4-utd1`: 3 seeds vmapped,
E = 4, K = 50, UTD 1, h1hand-sit_simple-v0) from the latest checkpoint of a study arm
(`--state`: its buffer, networks and planner; without it, a fresh state is stepped through a
shortened seed phase). Timed, each alone, as the study runs them (vmapped over the seeds):
  fused step    one `Train.step` call (K vectorised steps: plan, env step, buffer add and
                E * UTD updates each): what the study's loop calls;
  plan, env step, buffer add, buffer sample, update
                the same work of one call as separate jitted scans (`bench_train._parts`);
                "fusion" is the fused step minus their sum;
  eval          one evaluation (4 episodes per seed, planner and prior, run until every
                episode ends), done every 10k env steps;
  checkpoint    one atomic save of the vmapped train state (buffer included), every 10k;
  host          per call: fetching the metrics, the NaN and blow-up checks, the CSV rows.
Each row is then scaled to 1k env steps per seed (a call is K * E = 200 of them). Medians of
`--repeats` rounds, timed round-robin. Run it on an idle machine: it is a timing.
"""

from __future__ import annotations

import dataclasses
import json
import statistics
import tempfile
import time
from pathlib import Path

import jax
import numpy as np
import tyro

from experiments.bench.bench_train import _parts, _timings
from experiments.paper.common import arm_env
from experiments.studies.sit_simple import config
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.runlog import CsvLog
from sirl_jax.train import make_train

EVAL_EVERY = 10_000


@dataclasses.dataclass(frozen=True)
class Args:
    state: str | None = None
    """A study arm's directory (results/sit_simple/study/ARM): start from its latest checkpoint."""
    seeds: int = 3
    repeats: int = 5
    out: str | None = None
    """Also write the table as JSON here."""


def _state(train, seeds: int, arm_dir: Path | None):
    """The S-seed train state: a study checkpoint's, or a fresh one stepped until it plans."""
    keys = jax.random.split(jax.random.PRNGKey(0), seeds)
    init = jax.vmap(train.init)
    if arm_dir is not None:
        ckpt = Checkpointer(arm_dir / "checkpoints")
        try:
            step = ckpt.latest_step()
            if step is None:
                raise SystemExit(f"error: {arm_dir / 'checkpoints'} holds no checkpoint")
            state = ckpt.restore({"state": jax.eval_shape(init, keys)}, step)["state"]
        finally:
            ckpt.close()
        print(f"state: {arm_dir}, checkpoint at {step:,} env steps per seed")
        return state
    state = jax.jit(init)(keys)
    step = jax.jit(jax.vmap(train.step))
    while not bool(np.all(state.planning)):
        state, _ = step(state)
    print("state: fresh, stepped through the seed phase")
    return state


def _host_work(metrics, seeds: int, csv: CsvLog, repeats: int) -> float:
    """Median seconds of the study loop's host work on one call's metrics (`run_arm`)."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        m = jax.device_get(metrics)
        bool(m["nonfinite_loss"].any() or (m["env/blowups"] > 0).any())
        csv.extend([{"seed": s, "env_steps": int(m["env_steps"][s]),
                     "episode_return": float(m["episode/return"][s]),
                     "episode_length": float(m["episode/length"][s]),
                     "r_max": float(m["r_max"][s]), "updates": int(m["updates"][s])}
                    for s in range(seeds)])  # fmt: skip
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _once(fn, *args) -> float:
    t = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - t


def main(args: Args) -> None:
    enable_compilation_cache()
    arm_dir = Path(args.state) if args.state else None
    cfg = config("e4-utd1", 1.0, 100_000, eval_every=EVAL_EVERY)
    if arm_dir is None:  # a short seed phase, so that a fresh state plans soon
        cfg = dataclasses.replace(cfg, train=dataclasses.replace(cfg.train, seed_steps=400,
                                                                 pretrain=False))  # fmt: skip
    tc = cfg.train
    train = make_train(cfg, arm_env(cfg))
    state = _state(train, args.seeds, arm_dir)
    k, e = tc.chunk_steps, tc.num_envs
    per_call = k * e  # env steps per seed per call
    step = jax.jit(jax.vmap(train.step))  # no donation: the same state is timed repeatedly
    cases = {"fused step": (step, (state,))}
    cases.update(_parts(train, state, k, e, round(e * tc.utd), vmapped=True))
    times = _timings(cases, args.repeats)
    med = {name: statistics.median(t) for name, t in times.items()}

    evaluate = jax.jit(jax.vmap(train.evaluate))
    eval_keys = jax.random.split(jax.random.PRNGKey(2), args.seeds)
    jax.block_until_ready(evaluate(state, eval_keys))  # compile
    evals = [_once(evaluate, state, jax.random.split(jax.random.PRNGKey(3 + r), args.seeds))
             for r in range(max(2, args.repeats // 2))]  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = Checkpointer(Path(tmp) / "checkpoints", max_to_keep=2)
        saves = []
        for r in range(max(2, args.repeats // 2)):
            t = time.perf_counter()
            ckpt.save((r + 1) * EVAL_EVERY, {"state": state}, {"wall_s": 0.0, "cpu_s": 0.0})
            saves.append(time.perf_counter() - t)
        ckpt.close()
        host = _host_work(step(state)[1], args.seeds, CsvLog(Path(tmp) / "train.csv"),
                          args.repeats)  # fmt: skip

    calls = 1_000 / per_call  # calls per 1k env steps per seed
    parts = ["plan", "env step", "buffer add", "buffer sample", "update"]
    rows = {p: med[p] * calls for p in parts}
    rows["fusion (fused - sum of parts)"] = (med["fused step"] - sum(med[p] for p in parts)) * calls
    rows["eval"] = statistics.median(evals) * 1_000 / EVAL_EVERY
    rows["checkpoint"] = statistics.median(saves) * 1_000 / EVAL_EVERY
    rows["host"] = host * calls
    total = sum(rows.values())
    print(f"\n{tc.task}, {args.seeds} seeds vmapped x E={e}, K={k}, UTD {tc.utd:g}, "
          f"B={cfg.agent.batch_size}; {jax.devices()[0].platform}")
    print(f"| {'part':<30} | {'s per 1k env steps per seed':>27} | {'share':>6} |")
    print(f"|{'-' * 32}|{'-' * 29}|{'-' * 8}|")
    for name, v in rows.items():
        print(f"| {name:<30} | {v:27.2f} | {v / total:6.1%} |")
    print(f"| {'total':<30} | {total:27.2f} | {'':>6} |")
    print(f"fused step alone: {med['fused step']:.3f} s per call = "
          f"{per_call / med['fused step']:.1f} env steps/s per seed; with eval, checkpoint and "
          f"host work: {1_000 / total:.1f} env steps/s per seed")  # fmt: skip
    if args.out:
        Path(args.out).write_text(json.dumps({
            "task": tc.task, "seeds": args.seeds, "num_envs": e, "chunk_steps": k,
            "s_per_1k_env_steps_per_seed": {n: round(v, 3) for n, v in rows.items()},
            "total": round(total, 3), "fused_s_per_call": round(med["fused step"], 4),
            "eval_s": round(statistics.median(evals), 2),
            "checkpoint_s": round(statistics.median(saves), 2)}, indent=1) + "\n")  # fmt: skip


if __name__ == "__main__":
    main(tyro.cli(Args))
