"""Where the 5M `update` spends its time on CPU: its pieces alone, and ablations side by side.

    .venv/bin/python -m experiments.bench.bench_update_parts [--rounds 7]

Pieces (forward + backward of one at a time, h1hand sizes O = 151, A = 61, B = 256):
world-model loss, the Q ensemble with and without dropout, the policy loss, the world-model
Adam step, and one hidden layer ([768, 573] -> 512) as NormedLinear (Dense + LayerNorm + Mish)
forward and forward + backward, and as Dense + ReLU. Ablations of the whole update (not
options: they leave the reference architecture): `dropout=0`, Mish -> ReLU, and both. Every
case is compiled first, then all are timed round-robin for `--rounds` rounds (median), so a
change of machine load hits every row alike;
"mm ms" is the row's analytic FLOPs at the rate of a jitted [768, 512] @ [512, 512] matmul
measured in the same run.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import statistics
import time
from unittest import mock

import jax
import jax.numpy as jnp
import optax

from experiments.bench.bench_agent import (
    matmul_gflops,
    module_flops,
    synthetic_batch,
    update_flops,
)
from sirl_jax.agent import AgentConfig, make_agent
from sirl_jax.agent import losses as L
from sirl_jax.agent import math as am
from sirl_jax.agent.agent import _wm_optimizer, wm_keys
from sirl_jax.agent.networks import NormedLinear
from sirl_jax.agent.world_model import make_world_model
from sirl_jax.types import Batch

O, A = 151, 61


def _batch(cfg: AgentConfig) -> Batch:
    return synthetic_batch(cfg, O, A, jax.random.PRNGKey(1))


def _update_case(cfg: AgentConfig, relu: bool = False):
    """(jitted update compiled now, args); `relu` traces the networks with ReLU for Mish."""
    agent = make_agent(cfg, O, A, episode_length=1000)
    r_max = jnp.float32(100.0)
    args = (agent.init(jax.random.PRNGKey(0)), _batch(cfg), r_max, jax.random.PRNGKey(2))
    with mock.patch("jax.nn.mish", jax.nn.relu) if relu else contextlib.nullcontext():
        compiled = jax.jit(agent.update).lower(*args).compile()
    return compiled, args


def _piece_cases(cfg: AgentConfig) -> dict[str, tuple]:
    """Forward + backward of the world-model loss, the Q ensemble, the policy loss; Adam."""
    agent = make_agent(cfg, O, A, episode_length=1000)
    wm = make_world_model(cfg, A)
    state = agent.init(jax.random.PRNGKey(0))
    batch, key = _batch(cfg), jax.random.PRNGKey(2)
    params = state.params
    wm_params = {n: params[n] for n in wm_keys(cfg)}
    H, B, Z = cfg.horizon, cfg.batch_size, cfg.arch.latent_dim
    zs = jax.random.uniform(key, (H + 1, B, Z))
    y = jnp.ones((H, B))

    def wm_grad(p, k):
        loss = lambda p: L.world_model_loss(
            wm, cfg, 0.99, p, params["policy"], state.target_qs, batch, k
        )[0]
        return jax.grad(loss)(p)

    def q_grad(qs, k):
        def loss(qs):
            logits = wm.q_logits(qs, zs[:-1], batch.action, k)
            return am.two_hot_ce(logits, y[None], cfg.num_bins, cfg.vmin, cfg.vmax).sum()

        return jax.grad(loss)(qs)

    def pi_grad(p, k):
        loss = lambda p: L.policy_loss(
            wm, cfg, p, params["qs"], zs, state.scale, batch, jnp.float32(100.0), k
        )[0]
        return jax.grad(loss)(p)

    tx = _wm_optimizer(cfg)
    grads = jax.tree.map(jnp.ones_like, wm_params)

    def adam(p, g, s):
        u, s = tx.update(g, s, p)
        return optax.apply_updates(p, u), s

    # One hidden layer of the Q/reward/dynamics heads alone: [H*B, Z + A] -> mlp_dim.
    rows, width = H * B, cfg.arch.mlp_dim
    layer = NormedLinear(width)
    x = jax.random.normal(key, (rows, Z + A))
    layer_params = layer.init(key, x)
    relu_layer = lambda p, x: jax.nn.relu(x @ p["params"]["Dense_0"]["kernel"])
    layer_flops = 2 * rows * (Z + A) * width

    def f_and_b(fn):
        return lambda p, x: jax.grad(lambda p, x: fn(p, x).sum(), argnums=(0, 1))(p, x)

    f = module_flops(cfg, O, A)
    q_flops = 3 * cfg.arch.num_q * H * B * f["q"]
    return {
        "world-model loss f+b": (wm_grad, (wm_params, key), None),
        "Q ensemble f+b, dropout": (q_grad, (params["qs"], key), q_flops),
        "Q ensemble f+b, no dropout": (q_grad, (params["qs"], None), q_flops),
        "policy loss f+b": (pi_grad, (params["policy"], key), None),
        "world-model Adam": (adam, (wm_params, grads, state.wm_opt_state), None),
        "layer Dense+LN+Mish fwd": (layer.apply, (layer_params, x), layer_flops),
        "layer Dense+LN+Mish f+b": (f_and_b(layer.apply), (layer_params, x), 3 * layer_flops),
        "layer Dense+ReLU f+b": (f_and_b(relu_layer), (layer_params, x), 3 * layer_flops),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()
    if args.rounds < 1:
        raise SystemExit(f"--rounds must be >= 1, got {args.rounds}")
    cfg = AgentConfig()
    flops = update_flops(cfg, O, A)
    cases: dict[str, tuple] = {}
    for name, (fn, fn_args, fl) in _piece_cases(cfg).items():
        cases[name] = (jax.jit(fn).lower(*fn_args).compile(), fn_args, fl)
    for name, c, relu in (
        ("update", cfg, False),
        ("update, dropout=0", dataclasses.replace(cfg, dropout=0.0), False),
        ("update, Mish -> ReLU", cfg, True),
        ("update, ReLU, dropout=0", dataclasses.replace(cfg, dropout=0.0), True),
    ):
        cases[name] = (*_update_case(c, relu), flops)
    for fn, fn_args, _ in cases.values():
        jax.block_until_ready(fn(*fn_args))  # warm
    times = {name: [] for name in cases}
    for _ in range(args.rounds):
        for name, (fn, fn_args, _) in cases.items():
            t = time.perf_counter()
            jax.block_until_ready(fn(*fn_args))
            times[name].append((time.perf_counter() - t) * 1e3)
    gfs = matmul_gflops(cfg.horizon * cfg.batch_size, 512, 512)
    print(f"backend={jax.default_backend()} 5M O={O} A={A} B={cfg.batch_size}; "
          f"matmul {gfs:.0f} GFLOP/s; {args.rounds} rounds")  # fmt: skip
    print(f"| {'piece':<30} | {'ms':>7} | {'mm ms':>7} | {'ratio':>6} |")
    print(f"|{'-' * 32}|{'-' * 9}|{'-' * 9}|{'-' * 8}|")
    for name, (_, _, fl) in cases.items():
        ms = statistics.median(times[name])
        mm = f"{fl / (gfs * 1e6):7.1f}" if fl else f"{'':>7}"
        ratio = f"{ms / (fl / (gfs * 1e6)):6.2f}" if fl else f"{'':>6}"
        print(f"| {name:<30} | {ms:7.1f} | {mm} | {ratio} |")


if __name__ == "__main__":
    main()
