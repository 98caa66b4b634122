"""Throughput of the fused train step, its parts timed alone, and the SIRL term's cost (CPU).

    .venv/bin/python -m experiments.bench.bench_train            # tiny config + 5M config
    .venv/bin/python -m experiments.bench.bench_train --no-full  # tiny config only

Rows (pendulum swing-up, 50-step episodes so the buffer fills fast, after the seed phase so
every chunk plans and updates):
  fused step      env steps/s of `Train.step` (K vectorised steps: act, env, buffer add,
                  E * utd updates each), the number a run sees.
  parts alone     the same work as separate jitted scans: env steps, MPPI plans, buffer adds,
                  buffer samples, updates on a fixed batch. overhead = fused / sum(parts) - 1.
  SIRL cost       `agent.update` with beta = 1 vs SirlConfig(enabled=False), same batch.
Medians of `--repeats` rounds, timed round-robin; ratios are medians of per-round ratios.
The machine is shared, so only compare rows of one run.
"""

from __future__ import annotations

import dataclasses
import statistics
import time

import jax
import jax.numpy as jnp
import tyro

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs.classic import PendulumSwingup
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.train import Train, make_train
from sirl_jax.types import Batch

T = 50


@dataclasses.dataclass(frozen=True)
class Args:
    full: bool = True
    """Also time the reference 5M agent (E = 1, a few chunks)."""
    repeats: int = 7
    """Timed calls per row (median reported)."""


def _timings(cases: dict, repeats: int) -> dict[str, list[float]]:
    """Seconds per call of each `name: (fn, args)`, timed round-robin so that load changes on
    a shared machine hit every case alike; ratios are then taken within a round."""
    for fn, args in cases.values():
        jax.block_until_ready(fn(*args))  # compile + warm
    times = {name: [] for name in cases}
    for _ in range(repeats):
        for name, (fn, args) in cases.items():
            t = time.perf_counter()
            jax.block_until_ready(fn(*args))
            times[name].append(time.perf_counter() - t)
    return times


def _warm_state(train: Train):
    """A state past the seed phase (planning, buffer sampleable)."""
    state = jax.jit(train.init)(jax.random.PRNGKey(0))
    step = jax.jit(train.step)  # no donation: the same state is timed repeatedly
    while not bool(state.planning):
        state, _ = step(state)
    return state, step


def _parts(train: Train, state, k: int, e: int, n_upd: int, vmapped: bool = False):
    """Jitted functions doing one chunk's work per part, each alone. vmapped: `state` holds S
    seeds (leading axis), and each part runs vmapped over them as the S-seed program does
    (the update's fixed batch is seed 0's)."""
    agent, buffer, vec = train.agent, train.buffer, train.vec_env
    a = agent.action_size
    key = jax.random.PRNGKey(1)
    one = jax.tree.map(lambda x: x[0], state) if vmapped else state
    jit = (lambda f: jax.jit(jax.vmap(f))) if vmapped else jax.jit

    @jit
    def env_part(env_state):
        def body(s, _):
            return vec.step(s, jnp.zeros((e, a))), None

        return jax.lax.scan(body, env_state, None, length=k)[0]

    @jit
    def plan_part(agent_state, planner, obs, first):
        def body(p, kk):
            act, p = agent.plan(agent_state, p, obs, first, kk)
            return p, act

        return jax.lax.scan(body, planner, jax.random.split(key, k))

    @jit
    def add_part(buf, obs):
        def body(b, _):
            zeros = jnp.zeros((e,), bool)
            return buffer.add(b, obs, jnp.zeros((e, a)), jnp.zeros(e), obs, zeros, zeros), None

        return jax.lax.scan(body, buf, None, length=k)[0]

    @jit
    def sample_part(buf):
        return jax.lax.map(lambda kk: buffer.sample(buf, kk), jax.random.split(key, k * n_upd))

    batch = buffer.sample(one.buffer, key)

    @jit
    def update_part(agent_state):
        # The metrics are part of an update's work: sum them so that XLA cannot drop them.
        def body(i, carry):
            s, total = carry
            s, m = agent.update(s, batch, buffer.r_max(one.buffer), jax.random.fold_in(key, i))
            return s, total + sum(jnp.mean(v) for v in m.values())

        return jax.lax.fori_loop(0, k * n_upd, body, (agent_state, jnp.zeros(())))

    return {
        "env step": (env_part, (state.env,)),
        "plan": (plan_part, (state.agent, state.planner, state.env.obs, state.env.first)),
        "buffer add": (add_part, (state.buffer, state.env.obs)),
        "buffer sample": (sample_part, (state.buffer,)),
        "update": (update_part, (state.agent,)),
    }


def bench_config(name: str, agent_cfg: AgentConfig, e: int, k: int, repeats: int) -> None:
    train_cfg = TrainConfig(
        task="pendulum",
        steps=1_000_000,
        num_envs=e,
        chunk_steps=k,
        seed_steps=e * T,
        pretrain=False,
        buffer_size=max(20_000, 4 * e * T),
    )
    train = make_train(Config(agent=agent_cfg, train=train_cfg), PendulumSwingup(T))
    state, step = _warm_state(train)
    n = train.steps_per_call
    cases = {"fused step": (step, (state,))}
    cases.update(_parts(train, state, k, e, round(e * train_cfg.utd)))
    times = _timings(cases, repeats)
    med = {name: statistics.median(t) for name, t in times.items()}
    parts = [name for name in times if name != "fused step"]
    total = sum(med[p] for p in parts)
    overhead = statistics.median(
        f / sum(times[p][r] for p in parts) - 1 for r, f in enumerate(times["fused step"])
    )
    fused = med["fused step"]
    print(f"\n{name}: E={e}, K={k}, utd=1, B={agent_cfg.batch_size}, {n} transitions per call")
    print(f"| {'what':<16} | {'s per call':>10} | {'env steps/s':>11} | {'share':>6} |")
    print(f"|{'-' * 18}|{'-' * 12}|{'-' * 13}|{'-' * 8}|")
    print(f"| {'fused step':<16} | {fused:10.3f} | {n / fused:11.1f} | {'':>6} |")
    for part in parts:
        print(f"| {part:<16} | {med[part]:10.3f} | {'':>11} | {med[part] / total:6.1%} |")
    print(f"| {'sum of parts':<16} | {total:10.3f} | {n / total:11.1f} | {'':>6} |")
    print(f"fused overhead vs sum of parts (median of per-round ratios): {overhead:+.1%}")


def bench_sirl(agent_cfg: AgentConfig, repeats: int, num_updates: int = 50) -> None:
    env = PendulumSwingup(T)
    cases = {}
    for label, sirl in (("beta=1", SirlConfig(beta=1.0)), ("disabled", SirlConfig(enabled=False))):
        cfg = dataclasses.replace(agent_cfg, sirl=sirl)
        agent = make_agent(cfg, env.observation_size, env.action_size, T)
        key = jax.random.PRNGKey(0)
        b, h, o, a = cfg.batch_size, cfg.horizon, env.observation_size, env.action_size
        batch = Batch(
            obs=jax.random.normal(key, (h + 1, b, o)),
            action=jax.random.uniform(key, (h, b, a), minval=-1, maxval=1),
            reward=jax.random.uniform(key, (h, b)),
            terminated=jnp.zeros((h, b)),
            episode_return=jax.random.uniform(key, (b,), maxval=50.0),
        )

        @jax.jit
        def run(s, agent=agent, batch=batch, key=key):
            def body(i, s):
                return agent.update(s, batch, jnp.float32(50.0), jax.random.fold_in(key, i))[0]

            return jax.lax.fori_loop(0, num_updates, body, s)

        cases[label] = (run, (agent.init(key),))
    times = _timings(cases, repeats)
    pairs = zip(times["beta=1"], times["disabled"], strict=True)
    ratio = statistics.median(x / y for x, y in pairs)
    print(f"\nSIRL term cost ({agent_cfg.model_size}, B={agent_cfg.batch_size}):")
    print("| update      | ms per update |")
    print("|-------------|---------------|")
    for label, t in times.items():
        print(f"| {label:<11} | {statistics.median(t) / num_updates * 1e3:13.2f} |")
    print(f"SIRL overhead (median of per-round ratios): {ratio - 1:+.1%}")


def main(args: Args) -> None:
    enable_compilation_cache()
    tiny = AgentConfig.tiny(batch_size=32)
    bench_config("tiny agent", tiny, e=4, k=50, repeats=args.repeats)
    bench_sirl(tiny, args.repeats)
    if args.full:
        full = AgentConfig()
        bench_config("5M agent (reference)", full, e=1, k=4, repeats=max(2, args.repeats // 2))
        bench_sirl(full, max(2, args.repeats // 2), num_updates=5)


if __name__ == "__main__":
    main(tyro.cli(Args))
