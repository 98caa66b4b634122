"""The device benchmark: the GPU path's figures in one table, and the paper's runtime projected.

    python experiments/bench/device.py                  # on a GPU: about 8 min, compiles included
    python experiments/bench/device.py --quick          # CPU check (a test runs it): tiny sizes
    python experiments/bench/device.py --json out.json  # the table as JSON too
    python experiments/bench/device.py --rows agent env  # a second call: only these row groups

Runs without `make` from wheels on PYTHONPATH (the repository root included). Rows:
  env      h1hand-walk `VecEnv` control steps/s summed over E envs, a `lax.scan` of K steps,
           impl jax and warp, E in {1, 64, 1024, 8192} ("not installed" without warp-lang).
  matmul   the device's float32 matmul rate ([n, n] @ [n, n], default precision), TFLOP/s.
  agent    the 5M agent's plan (E = 1, 16) and update: ms per call, analytic GFLOP
           (experiments/bench/bench_agent.py), achieved TFLOP/s, and time / matmul time (the
           agent core's target: 1.5x).
  train    the fused `Train.step`, env steps/s per seed, 3 seeds vmapped: the paper's setting
           (E = 1, UTD 1) and a throughput setting (E = 16, UTD 1/16 per env), SIRL on and off.
  project  hours for 2M steps x 3 seeds on walk, reach and hurdle (both settings), beside the
           paper's V100 hours. Walk's fused step is measured; reach and hurdle replace its env
           share by their own env step at 3 worlds (the task scenes differ only in physics).
  fasttd3  the FastTD3 learner's fused `Train.step` at the `fasttd3-gpu` preset's sizes (1024
           envs, batch 32768, critic 1024 / actor 512, 2 critic updates per vectorised step),
           one seed, SIRL on: env steps/s, with critic updates/s in the note.
Train rows use 25-step episodes so the seed phase ends within a chunk (the per-step cost is
that of 1000-step ones). Rows run in priority order (the paper's projection first, Warp last);
a row starts only within `--budget` seconds (default 360, so the last one and the table end
inside 8 minutes, compiles included); a row past it reads "n/a: ..." (rerun: the persistent
compilation cache keeps what compiled), and so does a row that failed ("n/a: error: ...").
`--quick` keeps every row but sizes it tiny (the pendulum for every task, the tiny agent, the
throughput setting at the paper setting's sizes, so its train rows reuse those compiles) and
compiles with XLA's backend optimisations off: its figures check the script, nothing else.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a file: make `experiments` and `sirl_jax` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import jax
import jax.numpy as jnp
import numpy as np

from experiments.bench.bench_agent import plan_flops, synthetic_batch, update_flops
from experiments.paper.common import PAPER_HOURS
from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import VecEnv, load
from sirl_jax.envs.physics import OVERFLOW_METRIC, Physics, raise_on_overflow, warp_unavailable
from sirl_jax.presets import get_preset
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.train import make_train

RUN_STEPS, SEEDS = 2_000_000, 3
ROW_GROUPS = ("matmul", "paper", "agent", "env", "fasttd3", "throughput", "warp")
QUICK_XLA_FLAGS = "--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true"


@dataclasses.dataclass(frozen=True)
class Sizes:
    """What each row measures; `quick()` is the same table sized for a CPU test."""

    env_task: str = "h1hand-walk-v0"
    tasks: tuple[tuple[str, str], ...] = (
        ("walk", "h1hand-walk-v0"), ("reach", "h1hand-reach-v0"), ("hurdle", "h1hand-hurdle-v0"),
    )  # fmt: skip
    env_envs: tuple[int, ...] = (1, 64, 1024, 8192)
    env_chunk: int = 20
    agent: AgentConfig = dataclasses.field(default_factory=lambda: AgentConfig(entropy_form="v1"))
    plan_envs: tuple[int, ...] = (1, 16)
    matmul_n: int = 4096
    settings: tuple[tuple[str, int, float], ...] = (("paper", 1, 1.0), ("throughput", 16, 1 / 16))
    train_chunk: int = 50
    episode_length: int = 25
    repeats: int = 3
    caveat: str = ""
    fasttd3: AgentConfig = dataclasses.field(
        default_factory=lambda: get_preset("fasttd3-gpu").agent)
    fasttd3_envs: int = 1024

    @classmethod
    def quick(cls) -> Sizes:
        return cls(
            env_task="pendulum",
            # reach and hurdle by the full id: the projection's env swap runs (a no-op here)
            tasks=(("walk", "pendulum"), ("reach", "pendulum-swingup-v0"),
                   ("hurdle", "pendulum-swingup-v0")),  # fmt: skip
            env_envs=(1, 3),
            env_chunk=5,
            agent=AgentConfig.tiny(),
            plan_envs=(1, 4),
            matmul_n=128,
            settings=(("paper", 1, 1.0), ("throughput", 1, 1.0)),
            train_chunk=10,
            episode_length=10,
            repeats=2,
            caveat="quick sizes (pendulum, tiny agent), not a projection; ",
            fasttd3=get_preset("fasttd3-smoke").agent,
            fasttd3_envs=4,
        )


def row_names(sizes: Sizes) -> list[str]:
    """Every row of the table, in print order."""
    task, envs = sizes.env_task, sizes.env_envs
    names = [f"env {task} impl={i} E={e}" for i in ("jax", "warp") for e in envs]
    names += ["matmul float32"]
    names += [f"agent plan E={e}" for e in sizes.plan_envs] + ["agent update"]
    for name, e, _ in sizes.settings:
        names += [f"train {name} S={SEEDS} E={e} sirl={s}" for s in ("on", "off")]
        names += [f"train {name} SIRL overhead"]
    for task, _ in sizes.tasks:
        for name, _, _ in sizes.settings:
            names += [f"project {task} {name} {arm}" for arm in ("TDMPBC", "TD-MPC2")]
    names += [f"fasttd3 S=1 E={sizes.fasttd3_envs}"]
    return names


def _timed(fn, repeats: int) -> tuple[float, float, object]:
    """(seconds of the first call, compile included; median seconds of `repeats` more; the
    last result)."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = jax.block_until_ready(fn())
        times.append(time.perf_counter() - t)
    return first, float(np.median(times)), out


def _shown(value) -> str:
    return value if isinstance(value, str) else f"{value:.4g}"


class Table:
    """Rows by name: value (a positive number, or a string saying why there is none), unit,
    note. `--json` rewrites the file after every row, so a killed run keeps what it measured."""

    def __init__(self, names: list[str], json_path: str | None, header: dict):
        self.rows = {n: {"value": "n/a: not reached", "unit": "", "note": ""} for n in names}
        self.json_path, self.header = json_path, header
        self.start = time.perf_counter()

    def set(self, name: str, value, unit: str = "", note: str = "") -> None:
        if name not in self.rows:
            raise KeyError(f"row {name!r} is not in the table")
        if not isinstance(value, str) and not (math.isfinite(value) and value > 0):
            value = f"n/a: measured {value!r}"
        self.rows[name] = {"value": value, "unit": unit, "note": note}
        line = f"{time.perf_counter() - self.start:5.0f} s  {name}: {_shown(value)} {unit} {note}"
        print(line.rstrip(), file=sys.stderr, flush=True)
        self.write()

    def write(self) -> None:
        if self.json_path:
            rows = [{"row": n, **r} for n, r in self.rows.items()]
            Path(self.json_path).write_text(json.dumps({**self.header, "rows": rows}, indent=1))

    def print(self) -> None:
        print("\n| row | value | unit | note |\n|---|---:|---|---|")
        for name, r in self.rows.items():
            print(f"| {name} | {_shown(r['value'])} | {r['unit']} | {r['note']} |")


# ------------------------------------------------------------------------------ measurements


@functools.cache
def env_seconds(task: str, impl: str, num_envs: int, chunk: int, repeats: int):
    """(seconds per vectorised control step, first call s) of `chunk` random-action steps of
    `num_envs` envs (a buffer overflow under Warp is an error)."""
    _, env = load(task, physics=Physics(impl, num_worlds=num_envs))
    vec = VecEnv(env, num_envs)

    @jax.jit
    def run(state, key):
        def body(s, k):
            a = jax.random.uniform(k, (num_envs, env.action_size), minval=-1.0, maxval=1.0)
            s = vec.step(s, a)
            return s, s.metrics.get(OVERFLOW_METRIC, jnp.zeros(num_envs))

        return jax.lax.scan(body, state, jax.random.split(key, chunk))

    state = jax.jit(vec.reset)(jax.random.PRNGKey(0))
    first, seconds, (_, overflow) = _timed(lambda: run(state, jax.random.PRNGKey(1)), repeats)
    raise_on_overflow(overflow, f"of {task}", env.sim.buffers)
    return seconds / chunk, first


def matmul_tflops(n: int, repeats: int) -> float:
    x = jax.random.normal(jax.random.PRNGKey(0), (n, n))
    w = jax.random.normal(jax.random.PRNGKey(1), (n, n))
    mm = jax.jit(jnp.matmul)
    return 2 * n**3 / _timed(lambda: mm(x, w), max(repeats, 10))[1] / 1e12


def agent_jobs(sizes: Sizes, obs: int, act: int) -> list[tuple[str, object, int]]:
    """(row, call, analytic FLOPs) of the plan rows and the update row."""
    cfg = sizes.agent
    agent = make_agent(cfg, obs, act, episode_length=1000)
    state = jax.jit(agent.init)(jax.random.PRNGKey(0))
    key = jax.random.PRNGKey(1)
    jobs = []
    for e in sizes.plan_envs:
        plan = jax.jit(agent.plan)
        args = (state, agent.init_planner(e), jax.random.normal(key, (e, obs)),
                jnp.zeros((e,), bool), key)  # fmt: skip
        flops = e * plan_flops(cfg, obs, act, agent.iterations)
        jobs.append((f"agent plan E={e}", lambda p=plan, a=args: p(*a), flops))
    update = jax.jit(agent.update)
    batch = synthetic_batch(cfg, obs, act, key)
    jobs.append(("agent update", lambda: update(state, batch, jnp.float32(100.0), key),
                 update_flops(cfg, obs, act)))  # fmt: skip
    return jobs


@functools.cache
def train_seconds(sizes: Sizes, task: str, num_envs: int, utd: float, sirl: bool,
                  agent: AgentConfig | None = None, seeds: int = SEEDS):  # fmt: skip
    """(seconds per chunk of S vmapped fused steps after the seed phase, first call s,
    non-finite count of the last chunk). `agent` replaces the sizes' TD-MPC2 agent."""
    if agent is None:
        agent = dataclasses.replace(sizes.agent, sirl=SirlConfig(enabled=sirl))
    t = sizes.episode_length
    steps = 4 * num_envs * (t + 1)
    train_cfg = TrainConfig(task=task, num_envs=num_envs, utd=utd, chunk_steps=sizes.train_chunk,
                            seed_steps=2 * t * num_envs, pretrain=False, steps=steps,
                            buffer_size=steps, eval_every=0)  # fmt: skip
    _, env = load(task, episode_length=t)
    train = make_train(Config(agent=agent, train=train_cfg), env)
    step = jax.jit(jax.vmap(train.step), donate_argnums=0)
    t0 = time.perf_counter()
    state = jax.jit(jax.vmap(train.init))(jax.random.split(jax.random.PRNGKey(0), seeds))
    state, metrics = jax.block_until_ready(step(state))
    first = time.perf_counter() - t0
    while not bool(np.all(jax.device_get(state.planning))):
        state, metrics = step(state)
    times = []
    for _ in range(sizes.repeats + 1):  # the first planning chunk is left out
        t1 = time.perf_counter()
        state, metrics = jax.block_until_ready(step(state))
        times.append(time.perf_counter() - t1)
    bad = int(np.sum(jax.device_get(metrics["env/blowups"] + metrics["nonfinite_loss"])))
    return float(np.median(times[1:])), first, bad


class Bench:
    """Runs the rows in priority order under the time budget; a failing row reads
    "n/a: error: ..." and the others still run."""

    def __init__(self, sizes: Sizes, table: Table, budget: float):
        self.sizes, self.table, self.budget = sizes, table, budget
        self.start = time.perf_counter()
        self.per_step: dict[tuple[str, bool], float] = {}  # seconds per vectorised env step
        self.mm = math.nan

    def run(self, row: str, fn) -> None:
        """Fills `row` with fn() -> (value, unit, note), unless past the budget or failing."""
        if time.perf_counter() - self.start > self.budget:
            self.table.set(row, f"n/a: over the {self.budget:.0f} s budget (rerun: compiles "
                                "are cached)")  # fmt: skip
            return
        try:
            self.table.set(row, *fn())
        except Exception as e:  # one bad row must not lose the others
            first = (str(e).strip().splitlines() or [""])[0][:200]
            self.table.set(row, f"n/a: error: {type(e).__name__}: {first}")

    def env_step(self, task: str, worlds: int) -> float:
        s = self.sizes
        return env_seconds(task, "jax", worlds, s.env_chunk, s.repeats)[0]

    def matmul(self) -> None:
        def fn():
            self.mm = matmul_tflops(self.sizes.matmul_n, self.sizes.repeats)
            n = self.sizes.matmul_n
            return self.mm, "TFLOP/s", f"[{n}, {n}] @ [{n}, {n}], default precision"

        self.run("matmul float32", fn)

    def agent(self, obs: int, act: int) -> None:
        for row, call, flops in agent_jobs(self.sizes, obs, act):

            def fn(call=call, flops=flops):
                first, seconds, _ = _timed(call, self.sizes.repeats)
                mm_seconds = flops / (self.mm * 1e12)
                note = (f"{flops / 1e9:.3g} GFLOP, {flops / seconds / 1e12:.3g} TFLOP/s, "
                        f"{seconds / mm_seconds:.2f}x its matmul time (target 1.5x), "
                        f"first call {first:.0f} s")  # fmt: skip
                return seconds * 1e3, "ms/call", note

            self.run(row, fn)

    def env(self, impl: str, num_envs: int, warp: str | None) -> None:
        s = self.sizes
        row = f"env {s.env_task} impl={impl} E={num_envs}"
        if impl == "warp" and warp is not None:
            self.table.set(row, "not installed" if "not installed" in warp else f"n/a: {warp}")
            return

        def fn():
            seconds, first = env_seconds(s.env_task, impl, num_envs, s.env_chunk, s.repeats)
            return num_envs / seconds, "steps/s", f"control steps, first call {first:.0f} s"

        self.run(row, fn)

    def train(self, setting: tuple[str, int, float]) -> None:
        s, (name, e, utd) = self.sizes, setting
        for sirl in (True, False):

            def fn(sirl=sirl):
                seconds, first, bad = train_seconds(s, s.tasks[0][1], e, utd, sirl)
                self.per_step[name, sirl] = seconds / s.train_chunk
                note = (f"per seed ({SEEDS * e * s.train_chunk / seconds:.4g} over the seeds),"
                        f" first call {first:.0f} s")  # fmt: skip
                if bad:
                    raise FloatingPointError(f"{bad} physics blow-ups or non-finite losses")
                return e * s.train_chunk / seconds, "env steps/s", note

            self.run(f"train {name} S={SEEDS} E={e} sirl={'on' if sirl else 'off'}", fn)

        def overhead():
            ratio = self.per_step[name, True] / self.per_step[name, False]
            return ratio, "x", "step time with SIRL / without"

        self.run(f"train {name} SIRL overhead", overhead)

    def fasttd3(self) -> None:
        s, e = self.sizes, self.sizes.fasttd3_envs

        def fn():
            seconds, first, bad = train_seconds(s, s.tasks[0][1], e, 1.0, True, s.fasttd3, 1)
            if bad:
                raise FloatingPointError(f"{bad} physics blow-ups or non-finite losses")
            critic = s.train_chunk * s.fasttd3.fasttd3.num_updates / seconds
            note = (f"{s.caveat}{critic:.4g} critic updates/s (batch "
                    f"{s.fasttd3.fasttd3.batch_size}), first call {first:.0f} s")  # fmt: skip
            return e * s.train_chunk / seconds, "env steps/s", note

        self.run(f"fasttd3 S=1 E={e}", fn)

    def project(self, setting: tuple[str, int, float]) -> None:
        """Hours for 2M steps per seed, S seeds vmapped: walk's fused step, with the env step
        of walk swapped for the task's at the setting's S * E worlds."""
        s, (name, e, _) = self.sizes, setting
        walk = s.tasks[0][1]
        for task, task_id in s.tasks:
            for arm, sirl in (("TDMPBC", True), ("TD-MPC2", False)):

                def fn(task=task, task_id=task_id, arm=arm, sirl=sirl):
                    seconds = self.per_step[name, sirl]  # KeyError: the train row failed
                    if task_id != walk:
                        worlds = SEEDS * e
                        seconds += self.env_step(task_id, worlds) - self.env_step(walk, worlds)
                    hours = RUN_STEPS / (e / seconds) / 3600
                    paper = PAPER_HOURS[task][0 if sirl else 1]
                    note = f"{s.caveat}paper (V100) {paper} h: {paper / hours:.3g}x faster"
                    if name != "paper":
                        note += f"; E={e} per seed, not the paper's setting"
                    return hours, "h", note

                self.run(f"project {task} {name} {arm}", fn)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes, for a CPU test")
    ap.add_argument("--json", default=None, help="also write the table as JSON to this file")
    ap.add_argument("--budget", type=float, default=None, help="seconds after which rows are "
                    "skipped (default 360; quick 600)")  # fmt: skip
    ap.add_argument("--rows", nargs="+", choices=ROW_GROUPS, default=None, metavar="GROUP",
                    help=f"only these groups of rows, in priority order (default all: "
                    f"{' '.join(ROW_GROUPS)}); the others read 'n/a: not reached'")  # fmt: skip
    args = ap.parse_args(argv)
    if args.quick:  # read when XLA's backend starts, i.e. at the first computation below
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {QUICK_XLA_FLAGS}".strip()
    sizes = Sizes.quick() if args.quick else Sizes()
    enable_compilation_cache()
    warp = warp_unavailable()
    header = {"backend": jax.default_backend(), "device": jax.devices()[0].device_kind,
              "quick": args.quick, "jax": jax.__version__, "warp": warp or "available"}  # fmt: skip
    print(f"device benchmark: {header}", file=sys.stderr, flush=True)
    table = Table(row_names(sizes), args.json, header)
    bench = Bench(sizes, table, args.budget or (600.0 if args.quick else 360.0))
    paper, throughput = sizes.settings
    _, probe = load(sizes.env_task)
    groups = {  # priority order: what the paper's projection needs first, Warp last
        "matmul": bench.matmul,
        "paper": lambda: (bench.train(paper), bench.project(paper)),
        "agent": lambda: bench.agent(probe.observation_size, probe.action_size),
        "env": lambda: [bench.env("jax", e, warp) for e in sizes.env_envs],
        "fasttd3": bench.fasttd3,
        "throughput": lambda: (bench.train(throughput), bench.project(throughput)),
        "warp": lambda: [bench.env("warp", e, warp) for e in sizes.env_envs],
    }
    chosen = set(args.rows or ROW_GROUPS)
    if "agent" in chosen:  # the agent rows' "x its matmul time" needs the matmul row
        chosen.add("matmul")
    for group in ROW_GROUPS:
        if group in chosen:
            groups[group]()
    table.write()
    table.print()
    print(f"\n{header}; {time.perf_counter() - bench.start:.0f} s")


if __name__ == "__main__":
    main()
