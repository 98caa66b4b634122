"""Run by tests/test_sharding.py in a subprocess with 4 virtual CPU devices:

    XLA_FLAGS=--xla_force_host_platform_device_count=4 \
        python tests/sharding_worker.py [--distributed]

Prints one JSON object: each layout's agreement with the unsharded run, the shardings seen,
the checkpoint round trips, the one-line errors and a `train --devices 4` run. With
--distributed it instead calls `jax.distributed.initialize` for one process (the multi-host
code path) and runs two chunks of layout envs.
"""

from __future__ import annotations

import json
import os
import socket
import sys
import tempfile

import jax
import numpy as np
from jax.sharding import PartitionSpec as P

if "--distributed" in sys.argv:
    from sirl_jax.sharding import initialize_multihost

    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    initialize_multihost(f"localhost:{port}", 1, 0)

from sirl_jax.agent import AgentConfig  # noqa: E402
from sirl_jax.config import Config, TrainConfig  # noqa: E402
from sirl_jax.envs.classic import PendulumSwingup  # noqa: E402
from sirl_jax.run.checkpoint import Checkpointer  # noqa: E402
from sirl_jax.sharding import (  # noqa: E402
    ENVS,
    SEEDS,
    batch_constraint,
    env_shardings,
    make_mesh,
    place,
    seed_shardings,
    sharded_step,
)  # fmt: skip
from sirl_jax.train import make_train  # noqa: E402

CHUNKS = 3


def config(num_envs: int) -> Config:
    # T = 20: each env ends an episode within the 80 seed steps; chunk 2 pretrains (40
    # updates), chunk 3 plans and runs 2 updates per vectorised step.
    train = TrainConfig(task="pendulum", steps=10_000, num_envs=num_envs, chunk_steps=10,
                        seed_steps=80, utd=0.5, buffer_size=400)  # fmt: skip
    return Config(agent=AgentConfig.tiny(batch_size=8), train=train)


def run(step, state, chunks: int = CHUNKS):
    for _ in range(chunks):
        state, metrics = step(state)
    return state, jax.device_get(metrics)


def max_diff(a, b) -> float:
    """Max |a - b| over the float leaves; NaN in both counts as equal, in one as inf."""
    out = 0.0
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        x, y = np.asarray(x), np.asarray(y)
        if not np.size(x) or not np.issubdtype(x.dtype, np.floating):
            continue
        both = np.isnan(x) & np.isnan(y)
        d = np.where(both, 0.0, np.abs(x.astype(np.float64) - y.astype(np.float64)))
        out = max(out, float(np.max(np.where(np.isnan(d), np.inf, d))))
    return out


def equal(a, b) -> bool:
    return all(np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True)
               for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True))  # fmt: skip


def stage(name: str) -> None:
    print(f"stage: {name}", file=sys.stderr, flush=True)


def error(fn) -> str:
    try:
        fn()
    except ValueError as e:
        return str(e)
    return "no error"


def multihost() -> dict:
    """After `initialize_multihost` for one process: one pretraining chunk of layout envs."""
    env, key = PendulumSwingup(episode_length=20), jax.random.PRNGKey(0)
    mesh = make_mesh(4, ENVS)
    train = make_train(config(4), env, constrain_batch=batch_constraint(mesh))
    shardings = env_shardings(jax.eval_shape(train.init, key), mesh, 4, 8)
    state, metrics = run(sharded_step(train.step, shardings), place(train.init(key), shardings), 2)
    return {"devices": jax.device_count(), "processes": jax.process_count(),
            "updates": int(metrics["updates"])}  # fmt: skip


def main() -> dict:
    out = {"devices": jax.device_count(), "processes": jax.process_count()}
    env = PendulumSwingup(episode_length=20)
    key = jax.random.PRNGKey(0)

    stage("envs: unsharded")
    # (b) one learner, E = 4 envs over 4 devices, batch split: gradient averaged by XLA. Two
    # chunks: random acting (the same transitions up to float rounding: 1 env per device is
    # compiled differently from 4) and 40 pretraining updates (parameters equal up to float
    # summation order). Chunk 3 plans: MPPI's elite selection
    # amplifies a 1e-7 parameter difference into other actions, so it is run, not compared.
    cfg = config(4)
    plain = make_train(cfg, env)
    ref, ref_m = run(jax.jit(plain.step), jax.jit(plain.init)(key), 2)
    stage("envs: sharded")
    mesh = make_mesh(4, ENVS)
    sharded = make_train(cfg, env, constrain_batch=batch_constraint(mesh))
    shardings = env_shardings(jax.eval_shape(sharded.init, key), mesh, 4, 8)
    step = sharded_step(sharded.step, shardings)
    got, got_m = run(step, place(sharded.init(key), shardings), 2)
    out["envs"] = {
        "updates": [int(ref_m["updates"]), int(got_m["updates"])],
        "params_max_diff": max_diff(ref.agent.params, got.agent.params),
        "buffer_max_diff": max_diff(ref.buffer, got.buffer),
        "buffer_ints_equal": equal(
            [x for x in jax.tree.leaves(jax.device_get(ref.buffer)) if x.dtype.kind != "f"],
            [x for x in jax.tree.leaves(jax.device_get(got.buffer)) if x.dtype.kind != "f"]),
        "buffer_split": got.buffer.obs.sharding.spec == P(ENVS),
        "params_replicated": all(x.sharding.is_fully_replicated
                                 for x in jax.tree.leaves(got.agent.params)),  # fmt: skip
        "buffer_shards": len(got.buffer.obs.addressable_shards),
    }
    got, got_m = step(got)
    out["envs"]["planning_chunk_updates"] = int(got_m["updates"])
    out["envs"]["planning_chunk_finite"] = bool(np.isfinite(np.asarray(got_m["train/total_loss"]
                                                                       )).all())  # fmt: skip

    stage("checkpoints")
    # Checkpoints: sharded -> unsharded targets, unsharded -> sharded targets.
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = Checkpointer(tmp)
        abstract = jax.eval_shape(plain.init, key)
        ckpt.save(1, {"state": got})
        back = ckpt.restore({"state": abstract}, 1)["state"]
        ckpt.save(2, {"state": ref})
        targets = jax.tree.map(lambda x, s: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=s),
                               abstract, shardings)  # fmt: skip
        onto = ckpt.restore({"state": targets}, 2)["state"]
        ckpt.close()
    out["checkpoint"] = {
        "sharded_to_unsharded": equal(jax.device_get(got), back),
        "unsharded_is_single_device": len(back.buffer.obs.devices()) == 1,
        "unsharded_to_sharded": equal(jax.device_get(ref), onto),
        "restored_split": onto.buffer.obs.sharding.spec == P(ENVS),
    }

    stage("seeds")
    # (a) S = 4 independent seeds over 4 devices, E = 2 each: no communication.
    cfg = config(2)
    plain = make_train(cfg, env)
    keys = jax.random.split(key, 4)
    init, step = jax.jit(jax.vmap(plain.init)), jax.vmap(plain.step)
    ref, _ = run(jax.jit(step), init(keys))
    mesh = make_mesh(4, SEEDS)
    shardings = seed_shardings(jax.eval_shape(jax.vmap(plain.init), keys), mesh)
    got, _ = run(sharded_step(step, shardings), place(init(keys), shardings))
    solo = jax.jit(plain.step)
    per_seed = [run(solo, jax.jit(plain.init)(k))[0] for k in keys]
    out["seeds"] = {
        "equal_to_vmapped": equal(jax.device_get(ref), jax.device_get(got)),
        "max_diff_to_vmapped": max_diff(ref, got),
        "max_diff_to_single_seed_runs": max(
            max_diff(jax.tree.map(lambda x, s=s: x[s], got), one)
            for s, one in enumerate(per_seed)),  # fmt: skip
        "split": got.agent.scale.sharding.spec == P(SEEDS),
    }

    abstract4 = jax.eval_shape(make_train(config(4), env).init, key)
    mesh4 = make_mesh(4, ENVS)
    out["errors"] = {
        "too_many_shards": error(lambda: make_mesh(5, ENVS)),
        "envs_not_dividing": error(lambda: env_shardings(abstract4, mesh4, 6, 8)),
        "batch_not_dividing": error(lambda: env_shardings(abstract4, mesh4, 4, 10)),
        "seeds_not_dividing": error(lambda: seed_shardings(
            jax.eval_shape(jax.vmap(plain.init), jax.random.split(key, 6)), mesh)),  # fmt: skip
    }

    stage("train command")
    # The train command with --devices 4 (layout envs), and one that asks for too many.
    from sirl_jax.run import cli

    with tempfile.TemporaryDirectory() as tmp:
        flags = ["--preset", "smoke", "--steps", "1200", "--chunk-steps", "25", "--eval-every",
                 "0", "--no-progress", "--no-tensorboard"]  # fmt: skip
        code = cli.main(["train", *flags, "--devices", "4", "--run-dir", f"{tmp}/run"])
        bad = cli.main(["train", *flags, "--devices", "8", "--run-dir", f"{tmp}/bad"])
        rows = [json.loads(ln) for ln in open(f"{tmp}/run/metrics.jsonl")]
        out["cli"] = {"code": code, "bad_code": bad, "bad_dir_made": os.path.exists(f"{tmp}/bad"),
                      "checkpoints": Checkpointer(f"{tmp}/run/checkpoints").steps(),
                      "updates": rows[-1]["updates"]}  # fmt: skip
    return out


if __name__ == "__main__":
    result = multihost() if "--distributed" in sys.argv else main()
    print("RESULT " + json.dumps(result), flush=True)
