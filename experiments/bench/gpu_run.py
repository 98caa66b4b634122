"""What a lent GPU measures first: two calls of at most 6 minutes each, learning first.

    python3 experiments/bench/gpu_run.py --call 1 --out $OUT   # FastTD3 + TDMPBC term learning
    python3 experiments/bench/gpu_run.py --call 2 --out $OUT   # the paper setting's cost per run
    python experiments/bench/gpu_run.py --call 1 --quick --out /tmp/q   # this CPU: tiny sizes

Call 1 trains the `fasttd3-gpu` preset (1024 envs, batch 32768, critic 1024 / actor 512,
beta 1) on h1hand-sit_simple-v0 for `--train-s` seconds of wall-clock after its compile. It
evaluates the actor (eval mode) over 16 episodes every `--eval-every-s` seconds, and records
the wall-clock to the first evaluation at HumanoidBench's success bar. Then, if the call's
`--budget-s` leaves time, it does the same on h1hand-stand-v0 (bar 800).

Call 2 times R runs of the paper setting (5M agent, MPPI 512 x 8, E = 1, UTD 1, SIRL on) in one
program for R = 3, then the largest first (24, 12, 6): env steps/s per run, the state's bytes
per run at the `gpu` preset's replay (2M transitions), the device's peak memory, and 2M steps for
every run projected against the paper's 12.5 V100-hours per run. The R runs are a sirl.beta
sweep (0, 1, 0, ...): the same program as R vmapped seeds. Then the planner.jax round trip:
serialise, reload and plan on the device; its actions must equal `agent.plan`'s.

Every row is appended to OUT/call<N>.jsonl and printed with the elapsed time as it is
measured, so a call stopped at its limit returns what it measured. The compilation cache is
`--cache` (default /tmp/sirl_jax_xla), which a warm machine keeps between back-to-back calls.
On the GPU machine, the packages it lacks travel as wheels: `experiments/bench/gpu_wheels.sh`.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a file: make `experiments` and `sirl_jax` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import jax
import jax.numpy as jnp

from experiments.bench.device_parts import (
    PAPER_RUN_HOURS,
    QUICK_XLA_FLAGS,
    RUN_STEPS,
    Sizes,
    peak_bytes,
    run_bytes,
    train_seconds,
)
from sirl_jax.agent import make_agent
from sirl_jax.config import Config
from sirl_jax.envs import load
from sirl_jax.presets import get_preset
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.export import export_planner
from sirl_jax.sweep import Sweep
from sirl_jax.train import make_train

LEARN_TASKS = ("h1hand-sit_simple-v0", "h1hand-stand-v0")
RUNS = (3, 24, 12, 6)


class Rows:
    """Appends each row to a JSONL file and prints it with the seconds since the call began."""

    def __init__(self, path: Path, header: dict):
        self.path, self.start = path, time.perf_counter()
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
        self.add("header", **header)

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def add(self, kind: str, **fields) -> None:
        row = {"kind": kind, "elapsed_s": round(self.elapsed(), 1), **fields}
        with self.path.open("a") as f:
            f.write(json.dumps(row) + "\n")
        shown = " ".join(f"{k}={v}" for k, v in fields.items())
        print(f"{row['elapsed_s']:6.0f} s  {kind}: {shown}", flush=True)


def learn_config(task: str, quick: bool, beta: float) -> Config:
    """The fasttd3-gpu preset on `task` (quick: fasttd3-smoke on its pendulum), 16-episode
    evaluations (quick: 4), at `beta`."""
    cfg = get_preset("fasttd3-smoke" if quick else "fasttd3-gpu")
    train = dataclasses.replace(cfg.train, task=cfg.train.task if quick else task,
                                eval_episodes=4 if quick else 16)  # fmt: skip
    sirl = dataclasses.replace(cfg.agent.sirl, beta=beta)
    return dataclasses.replace(cfg, train=train, agent=dataclasses.replace(cfg.agent, sirl=sirl))


def learn(rows: Rows, cfg: Config, betas: list[float], train_s: float, eval_every_s: float,
          deadline: float) -> None:  # fmt: skip
    """Trains one run per beta, as one sweep program (`sirl_jax.sweep`), for `train_s` after
    its compile (or until `deadline`, seconds since the call began), evaluating every run every
    `eval_every_s` of wall-clock and once at the end."""
    tc = cfg.train
    spec, env = load(tc.task, **tc.env_options)
    bar = env.success_bar
    train = make_train(cfg, env)
    sweep = Sweep.parse(1, [f"sirl.beta={','.join(f'{b:g}' for b in betas)}"])
    step = jax.jit(jax.vmap(train.step), donate_argnums=0)
    evaluate = jax.jit(jax.vmap(train.evaluate))
    label = dict(task=spec.id, envs=tc.num_envs, runs=len(sweep))
    t0 = time.perf_counter()
    state = jax.jit(sweep.init(train, cfg))()
    state, m = jax.block_until_ready(step(state))
    keys = jnp.stack([jax.random.PRNGKey(1)] * len(sweep))
    jax.block_until_ready(evaluate(state, keys))
    compile_s = time.perf_counter() - t0
    rows.add("compiled", **label, betas=betas, first_chunk_and_eval_s=round(compile_s, 1),
             bar=bar)  # fmt: skip
    end = min(time.perf_counter() + train_s, rows.start + deadline)
    train_wall = eval_wall = 0.0  # seconds in training chunks / in evaluations, after compile
    steps0, updates0 = int(m["env_steps"][0]), int(m["updates"][0])
    last_eval, first_bar, n = time.perf_counter(), [None] * len(sweep), 0
    while True:
        now = time.perf_counter()
        done = now >= end
        if done or now - last_eval >= eval_every_s:
            e0 = time.perf_counter()
            ev = jax.device_get(evaluate(state, jax.vmap(jax.random.fold_in, (0, None))(keys, n)))
            eval_wall += time.perf_counter() - e0
            last_eval, n = time.perf_counter(), n + 1
            steps, updates = int(m["env_steps"][0]), int(m["updates"][0])
            wall = round(compile_s + train_wall + eval_wall, 1)
            for r, beta in enumerate(betas):
                ret = float(ev["eval/policy_return"][r])
                if first_bar[r] is None and bar is not None and ret >= bar:
                    first_bar[r] = wall
                rows.add("eval", **label, beta=beta, wall_s=wall,
                         train_wall_s=round(train_wall, 1), env_steps=steps, updates=updates,
                         policy_return=round(ret, 1),
                         policy_return_std=round(float(ev["eval/policy_return_std"][r]), 1),
                         policy_length=round(float(ev["eval/policy_length"][r]), 1),
                         success=float(ev["eval/policy_success"][r]),
                         env_steps_per_s=round((steps - steps0) / max(train_wall, 1e-9), 1),
                         updates_per_s=round((updates - updates0) / max(train_wall, 1e-9), 1),
                         first_bar_wall_s=first_bar[r])  # fmt: skip
        if done:
            return
        c0 = time.perf_counter()
        state, m = step(state)
        m = jax.device_get(m)
        train_wall += time.perf_counter() - c0
        if m["nonfinite_loss"].any() or (m["env/blowups"] > tc.max_blowup_rate
                                         * tc.steps_per_call).any():  # fmt: skip
            raise FloatingPointError(f"non-finite losses or physics blow-ups after "
                                     f"{int(m['env_steps'][0]):,} env steps")  # fmt: skip


def call1(rows: Rows, args) -> None:
    for i, task in enumerate(LEARN_TASKS[:1] if args.quick else LEARN_TASKS):
        left = args.budget_s - rows.elapsed()
        if i > 0 and left < args.min_task_s:
            rows.add("skipped", task=task, why=f"{left:.0f} s of the budget left, under "
                     f"--min-task-s {args.min_task_s:g}")  # fmt: skip
            continue
        cfg = learn_config(task, args.quick, args.betas[0])
        guarded(rows, task, lambda cfg=cfg: learn(rows, cfg, args.betas, args.train_s,
                                                  args.eval_every_s, args.budget_s))  # fmt: skip


def call2(rows: Rows, args) -> None:
    sizes = Sizes.quick() if args.quick else Sizes()
    per_run, replay, capacity = run_bytes(sizes, args.quick)
    rows.add("state", bytes_per_run=per_run, replay_bytes_per_run=replay,
             replay_capacity=capacity, note="from the train state's shapes")  # fmt: skip
    for r in (1, 2) if args.quick else RUNS:
        if rows.elapsed() > args.budget_s:
            rows.add("skipped", runs=r, why=f"past the {args.budget_s:g} s budget")
            continue

        def one(r=r):
            seconds, first, bad = train_seconds(sizes, sizes.tasks[0][1], 1, 1.0, True, seeds=r,
                                                sweep=True)  # fmt: skip
            if bad:
                raise FloatingPointError(f"{bad} physics blow-ups or non-finite losses")
            rate = sizes.train_chunk / seconds  # env steps/s of each run (E = 1)
            hours = RUN_STEPS / rate / 3600
            rows.add("runs", runs=r, env_steps_per_s_per_run=round(rate, 2),
                     env_steps_per_s_total=round(rate * r, 1), first_call_s=round(first, 1),
                     hours_2m_all_runs=round(hours, 3), device_hours_per_run=round(hours / r, 3),
                     paper_v100_hours_per_run=round(PAPER_RUN_HOURS, 2),
                     per_run_vs_paper=round(PAPER_RUN_HOURS / (hours / r), 2),
                     state_gib_all_runs=round(per_run * r / 2**30, 2),
                     peak_bytes_so_far=peak_bytes(), quick=args.quick)  # fmt: skip

        guarded(rows, f"runs={r}", one)
    guarded(rows, "planner.jax", lambda: planner_round_trip(rows, sizes))


def planner_round_trip(rows: Rows, sizes: Sizes) -> None:
    """planner.jax's program serialised, reloaded and run on this device, against `agent.plan`
    in eval mode, from fresh parameters, over 3 steps of a carried planner state."""
    _, env = load(sizes.tasks[0][1])
    O, A, H = env.observation_size, env.action_size, sizes.agent.horizon
    agent = make_agent(dataclasses.replace(sizes.agent, plan_env_chunk=0), O, A,
                       env.episode_length)  # fmt: skip
    state = agent.init(jax.random.PRNGKey(0))
    blob = export_planner(agent, state, O, A, H).serialize()
    plan = jax.jit(jax.export.deserialize(blob).call)
    ref = jax.jit(lambda ps, o, f, k: agent.plan(state, ps, o, f, k, eval_mode=True))
    obs = jax.random.normal(jax.random.PRNGKey(2), (3, O))
    ps, prev, worst = agent.init_planner(1), jnp.zeros((H, A)), 0.0
    for t in range(3):
        key = jax.random.PRNGKey(10 + t)
        want, ps = ref(ps, obs[t][None], jnp.array([t == 0]), key)
        got, prev = plan(obs[t], prev, key)
        worst = max(worst, float(jnp.max(jnp.abs(got - want[0]))),
                    float(jnp.max(jnp.abs(prev - ps.prev_mean[0]))))  # fmt: skip
    rows.add("planner.jax", device=jax.devices()[0].device_kind, bytes=len(blob),
             max_abs_diff=worst, equal_within_1e_5=worst <= 1e-5)  # fmt: skip


def guarded(rows: Rows, what: str, fn) -> None:
    """Runs fn; an error becomes a row and the call goes on to its next measurement."""
    try:
        fn()
    except Exception as e:  # one failing measurement must not lose the others
        first = (str(e).strip().splitlines() or [""])[0][:300]
        rows.add("error", what=what, error=f"{type(e).__name__}: {first}")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--call", type=int, choices=(1, 2), required=True)
    ap.add_argument("--out", type=Path, required=True, help="folder for call<N>.jsonl")
    ap.add_argument("--quick", action="store_true", help="tiny sizes, for a CPU check")
    ap.add_argument("--budget-s", type=float, default=None,
                    help="seconds of the call after which nothing new starts (330; quick 120)")
    ap.add_argument("--train-s", type=float, default=None,
                    help="call 1: training seconds per task after the compile (240; quick 20)")
    ap.add_argument("--eval-every-s", type=float, default=None,
                    help="call 1: seconds between evaluations (30; quick 5)")
    ap.add_argument("--min-task-s", type=float, default=90.0,
                    help="call 1: the budget left that a second task needs to start")
    ap.add_argument("--betas", type=float, nargs="+", default=[1.0],
                    help="call 1: the arms, one run each in one sweep program (default the "
                    "TDMPBC term alone, beta 1; `--betas 1 0` adds plain FastTD3)")
    ap.add_argument("--cache", default=os.environ.get("SIRL_JAX_CACHE_DIR", "/tmp/sirl_jax_xla"))
    args = ap.parse_args(argv)
    q = args.quick
    args.budget_s = args.budget_s or (120.0 if q else 330.0)
    args.train_s = args.train_s or (20.0 if q else 240.0)
    args.eval_every_s = args.eval_every_s or (5.0 if q else 30.0)
    if q:  # read when XLA's backend starts, i.e. at the first computation below
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {QUICK_XLA_FLAGS}".strip()
    cache = enable_compilation_cache(args.cache)
    rows = Rows(args.out / f"call{args.call}.jsonl", {
        "call": args.call, "backend": jax.default_backend(),
        "device": jax.devices()[0].device_kind, "jax": jax.__version__, "quick": q,
        "cache": str(cache), "budget_s": args.budget_s})  # fmt: skip
    (call1 if args.call == 1 else call2)(rows, args)
    rows.add("done", seconds=round(rows.elapsed(), 1))


if __name__ == "__main__":
    main()
