"""The device benchmark's parts: what each row measures (`Sizes`), the table, and the timed
measurements (env steps, matmul, the agent's plan and update, the fused train step), shared by
`device.py` and `gpu_run.py`."""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a file: make `experiments` and `sirl_jax` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import jax
import jax.numpy as jnp
import numpy as np

from experiments.bench.bench_agent import plan_flops, synthetic_batch, update_flops
from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import VecEnv, load
from sirl_jax.envs.physics import OVERFLOW_METRIC, Physics, raise_on_overflow
from sirl_jax.presets import get_preset
from sirl_jax.run.reference import paper_hours
from sirl_jax.train import make_train

RUN_STEPS, SEEDS = 2_000_000, 3
PAPER_RUN_HOURS = paper_hours()["walk"]["TDMPBC"] / 3  # 37.7 V100-h for 3 seeds, TDMPBC, walk
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
    sweep_runs: tuple[int, ...] = (3, 24, 12, 6)  # runs per program: 3, then the largest first
    tiny: bool = False  # the quick() sizes

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
            sweep_runs=(1, 2),
            tiny=True,
        )


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
                  agent: AgentConfig | None = None, seeds: int = SEEDS,
                  sweep: bool = False):  # fmt: skip
    """(seconds per chunk of S vmapped fused steps after the seed phase, first call s,
    non-finite count of the last chunk). `agent` replaces the sizes' TD-MPC2 agent. `sweep`:
    the S runs are a sweep, sirl.beta 0, 1, 0, ... in `state.agent.hyper` (the same program as
    S seeds: the values are state, not trace)."""
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
    if sweep:
        beta = jnp.arange(seeds, dtype=jnp.float32) % 2
        hyper = {**state.agent.hyper, "sirl_beta": beta}
        state = state.replace(agent=state.agent.replace(hyper=hyper))
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


def run_bytes(sizes: Sizes, quick: bool) -> tuple[int, int, int]:
    """(bytes of one run's train state at the `gpu` preset's replay capacity, of which the
    replay's, that capacity in transitions), from the state's shapes alone."""
    cfg = get_preset("smoke" if quick else "gpu")
    cfg = dataclasses.replace(cfg, agent=sizes.agent)
    _, env = load(sizes.tasks[0][1])
    state = jax.eval_shape(make_train(cfg, env).init, jax.random.PRNGKey(0))

    def nbytes(tree) -> int:
        return int(sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(tree)))

    return nbytes(state), nbytes(state.buffer), cfg.train.capacity


def peak_bytes() -> int | None:
    stats = jax.devices()[0].memory_stats() or {}
    return stats.get("peak_bytes_in_use")
