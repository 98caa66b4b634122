"""Benchmark of the jitted agent `update` and `plan` on CPU (5M preset, h1hand sizes).

Run: .venv/bin/python -m experiments.bench.bench_agent [--reps 3] [--envs 1 16]
Prints ms per call, analytic FLOPs per call, the machine's measured matmul throughput on matmuls of
the same sizes, the ratio of measured time to FLOPs / throughput, and compile times.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import jax
import jax.numpy as jnp

from sirl_jax.agent import AgentConfig, make_agent
from sirl_jax.types import Batch


def dense_flops(sizes: list[int]) -> int:
    """Multiply-add FLOPs per row of a chain of Dense layers with widths `sizes`."""
    return sum(2 * a * b for a, b in zip(sizes[:-1], sizes[1:], strict=False))


def module_flops(cfg: AgentConfig, obs: int, act: int) -> dict[str, int]:
    """FLOPs per row for each module (LayerNorm/Mish/softmax ignored: < 2% here)."""
    a = cfg.arch
    enc_hidden = [a.enc_dim] * max(a.num_enc_layers - 1, 1)
    za = a.latent_dim + act
    return {
        "enc": dense_flops([obs, *enc_hidden, a.latent_dim]),
        "dyn": dense_flops([za, a.mlp_dim, a.mlp_dim, a.latent_dim]),
        "rew": dense_flops([za, a.mlp_dim, a.mlp_dim, cfg.num_bins]),
        "pi": dense_flops([a.latent_dim, a.mlp_dim, a.mlp_dim, 2 * act]),
        "q": dense_flops([za, a.mlp_dim, a.mlp_dim, cfg.num_bins]),
    }


def plan_flops(cfg: AgentConfig, obs: int, act: int, iterations: int) -> int:
    """FLOPs of one single-env plan: pi rollouts + iterations x (H N (R + d) + N (pi + 2 Q))."""
    f = module_flops(cfg, obs, act)
    H, N, P = cfg.horizon, cfg.num_samples, cfg.num_pi_trajs
    per_iter = H * N * (f["rew"] + f["dyn"]) + N * (f["pi"] + 2 * f["q"])
    return f["enc"] + H * P * (f["pi"] + f["dyn"]) + iterations * per_iter


def update_flops(cfg: AgentConfig, obs: int, act: int) -> int:
    """FLOPs of one update; backward = 2x forward for weights and inputs, 1x for inputs only."""
    f = module_flops(cfg, obs, act)
    H, B, nq = cfg.horizon, cfg.batch_size, cfg.arch.num_q
    fwd_nograd = H * B * (f["enc"] + f["pi"] + 2 * f["q"])  # targets and TD target
    fwd_grad = B * f["enc"] + H * B * (f["dyn"] + f["rew"] + nq * f["q"])
    pi_grad = (H + 1) * B * f["pi"] + (H * B * f["pi"] if cfg.sirl.enabled else 0)
    q_input_grad = (H + 1) * B * 2 * f["q"]
    return fwd_nograd + 3 * fwd_grad + 3 * pi_grad + 2 * q_input_grad


def synthetic_batch(cfg: AgentConfig, obs: int, act: int, key: jax.Array) -> Batch:
    """A replay batch of the config's H and B with random observations and actions."""
    H, B = cfg.horizon, cfg.batch_size
    k_obs, k_act = jax.random.split(key)
    return Batch(
        obs=jax.random.normal(k_obs, (H + 1, B, obs)),
        action=jnp.tanh(jax.random.normal(k_act, (H, B, act))),
        reward=jnp.ones((H, B)),
        terminated=jnp.zeros((H, B)),
        episode_return=jnp.linspace(0.0, 100.0, B),
    )


def time_calls(fn, args, reps: int) -> float:
    """Median wall ms of `reps` calls (after one warm call)."""
    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append((time.perf_counter() - t) * 1e3)
    return sorted(times)[len(times) // 2]


def matmul_gflops(m: int, k: int, n: int, reps: int = 20) -> float:
    """Measured GFLOP/s of a jitted [m, k] @ [k, n] float32 matmul."""
    x = jax.random.normal(jax.random.PRNGKey(0), (m, k))
    w = jax.random.normal(jax.random.PRNGKey(1), (k, n))
    ms = time_calls(jax.jit(jnp.matmul), (x, w), reps)
    return 2 * m * k * n / (ms * 1e6)


def compile_timed(fn, *args, **static):
    t = time.perf_counter()
    compiled = jax.jit(fn, static_argnames=tuple(static)).lower(*args, **static).compile()
    return compiled, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--envs", type=int, nargs="+", default=[1, 16])
    ap.add_argument("--model-size", default="5M")
    ap.add_argument("--obs", type=int, default=151)
    ap.add_argument("--act", type=int, default=61)
    args = ap.parse_args()
    O, A = args.obs, args.act
    cfg = AgentConfig(model_size=args.model_size)
    agent = make_agent(dataclasses.replace(cfg, plan_env_chunk=0), O, A, episode_length=1000)
    state = agent.init(jax.random.PRNGKey(0))
    H, B, Z = cfg.horizon, cfg.batch_size, cfg.arch.latent_dim
    k = jax.random.PRNGKey(1)
    batch = synthetic_batch(cfg, O, A, k)
    print(
        f"backend={jax.default_backend()} devices={jax.devices()} model={args.model_size} "
        f"O={O} A={A} iterations={agent.iterations}"
    )
    rows = []
    upd, c_upd = compile_timed(agent.update, state, batch, jnp.float32(100.0), k)
    ms = time_calls(upd, (state, batch, k), args.reps)
    rows.append(("update B=256", ms, update_flops(cfg, O, A), matmul_gflops(H * B, Z, Z), c_upd))
    mapped = make_agent(dataclasses.replace(cfg, plan_env_chunk=1), O, A, episode_length=1000)
    for E in args.envs:
        ps = agent.init_planner(E)
        obs = jax.random.normal(k, (E, O))
        first = jnp.zeros((E,), bool)
        variants = [(" vmap", agent)] + ([(" map", mapped)] if E > 1 else [])
        for suffix, ag in variants:
            plan, c_plan = compile_timed(ag.plan, state, ps, obs, first, k, eval_mode=False)
            ms = time_calls(plan, (state, ps, obs, first, k), args.reps)
            flops = E * plan_flops(cfg, O, A, agent.iterations)
            gfs = matmul_gflops(E * cfg.num_samples, Z + A, cfg.arch.mlp_dim)
            rows.append((f"plan E={E}{suffix}", ms, flops, gfs, c_plan))
    print(
        f"{'call':<15}{'ms/call':>10}{'GFLOP':>9}{'mm GFLOP/s':>12}{'mm ms':>9}"
        f"{'ratio':>7}{'compile s':>11}"
    )
    for name, ms, flops, gfs, comp in rows:
        mm_ms = flops / (gfs * 1e6)
        print(
            f"{name:<15}{ms:>10.1f}{flops / 1e9:>9.2f}{gfs:>12.1f}{mm_ms:>9.1f}"
            f"{ms / mm_ms:>7.2f}{comp:>11.1f}"
        )
    plans = {r[0]: r[1] for r in rows if r[0].startswith("plan")}
    if len(plans) > 1:
        e_min, e_max = min(args.envs), max(args.envs)
        per1 = plans[f"plan E={e_min} vmap"] / e_min
        for name in (f"plan E={e_max} vmap", f"plan E={e_max} map"):
            perE = plans[name] / e_max
            print(
                f"plan ms per env: E={e_min} {per1:.1f}, {name} {perE:.1f} "
                f"(ratio {perE / per1:.2f}; <= 1 means E envs cost <= E x one env)"
            )


if __name__ == "__main__":
    main()
