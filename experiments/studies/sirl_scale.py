"""The TDMPBC term's two open scale choices, measured (docs/agent.md, "The term's scale").

    .venv/bin/python -m experiments.studies.sirl_scale --what init  # sirl_loss at initialisation
    .venv/bin/python -m experiments.studies.sirl_scale --what run   # clamped actions, h1hand run

`init`: one update of a freshly initialised agent at h1hand sizes (O 151, A 61) on a synthetic
batch whose buffer actions are uniform in [-1, 1], with a fraction of their components set to
exactly +-1 (what MPPI's clamp produces), for the tiny and the 5M model and both `bc_reduce`
choices. Prints sirl_loss against pi_rl_loss (the Q/S part).

`run`: a short h1hand-stand run (smoke preset's tiny agent, 4 envs) per `action_clip` value,
printing per chunk the fraction of clamped action components in the sampled batches
(`sirl/clamped_fraction`) and the policy's mean log sigma (`train/pi_log_std`, bounded by
`log_std_max` = 2). Not a test: nothing is asserted.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np
import tyro

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import load
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.train import make_train
from sirl_jax.types import Batch

O, A = 151, 61


@dataclasses.dataclass(frozen=True)
class Args:
    what: str = "init"
    """init | run."""
    task: str = "h1hand-stand-v0"
    steps: int = 5_000
    """run: env steps per action_clip value (1,000 of them random seed steps)."""
    clips: tuple[float, ...] = (1e-6, 1e-3)
    """run: the action_clip values compared."""


def _batch(cfg: AgentConfig, clamped: float, key: jax.Array) -> Batch:
    h, b = cfg.horizon, cfg.batch_size
    k_obs, k_act, k_clamp, k_sign = jax.random.split(key, 4)
    action = jax.random.uniform(k_act, (h, b, A), minval=-1.0, maxval=1.0)
    at_clamp = jax.random.uniform(k_clamp, (h, b, A)) < clamped
    sign = jnp.where(jax.random.uniform(k_sign, (h, b, A)) < 0.5, -1.0, 1.0)
    return Batch(
        obs=jax.random.normal(k_obs, (h + 1, b, O)),
        action=jnp.where(at_clamp, sign, action),
        reward=jnp.ones((h, b)),
        terminated=jnp.zeros((h, b)),
        episode_return=jnp.full((b,), 100.0),  # R = G: omega = beta = 1
    )


def at_init() -> None:
    print(f"{'model':>5} {'reduce':>6} {'clamped':>7} {'sirl_loss':>10} {'pi_rl_loss':>10}")
    for size in ("tiny", "5M"):
        for reduce in ("mean", "sum"):
            cfg = AgentConfig(model_size=size, sirl=SirlConfig(bc_reduce=reduce))
            agent = make_agent(cfg, O, A, 1000)
            key = jax.random.PRNGKey(0)
            state = agent.init(key)
            update = jax.jit(agent.update)
            for clamped in (0.0, 1 / 3):
                _, m = update(state, _batch(cfg, clamped, key), jnp.float32(100.0), key)
                print(f"{size:>5} {reduce:>6} {clamped:>7.2f} {float(m['sirl_loss']):>10.1f} "
                      f"{float(m['pi_rl_loss']):>10.3f}", flush=True)  # fmt: skip


def short_run(args: Args) -> None:
    _, env = load(args.task)
    for clip in args.clips:
        agent = AgentConfig.tiny(batch_size=32, sirl=SirlConfig(action_clip=clip))
        train_cfg = TrainConfig(task=args.task, steps=args.steps, num_envs=4, chunk_steps=50,
                                seed_steps=1_000, buffer_size=args.steps, eval_every=0)  # fmt: skip
        train = make_train(Config(agent=agent, train=train_cfg), env)
        state = jax.jit(train.init)(jax.random.PRNGKey(0))
        step = jax.jit(train.step, donate_argnums=0)
        start, rows = time.perf_counter(), []
        for _ in range(-(-args.steps // train_cfg.steps_per_call)):
            state, m = step(state)
            m = jax.device_get(m)
            if m["train/num_updates"] > 0:
                rows.append((int(m["env_steps"]), float(m["sirl/clamped_fraction"]),
                             float(m["train/pi_log_std"]),
                             float(m["train/sirl_loss"])))  # fmt: skip
                print(f"clip {clip:g} step {rows[-1][0]:>6}: clamped {rows[-1][1]:.3f}, log sigma "
                      f"{rows[-1][2]:+.2f}, sirl_loss {rows[-1][3]:.2f} "
                      f"({time.perf_counter() - start:.0f} s)", flush=True)  # fmt: skip
        fractions = np.array([r[1] for r in rows])
        print(f"clip {clip:g}: clamped fraction {fractions.mean():.3f} (min {fractions.min():.3f},"
              f" max {fractions.max():.3f}); final log sigma {rows[-1][2]:+.2f}", flush=True)


def main(args: Args) -> None:
    enable_compilation_cache()
    if args.what == "init":
        at_init()
    elif args.what == "run":
        short_run(args)
    else:
        raise SystemExit(f"error: what={args.what!r} is invalid; allowed: init, run")


if __name__ == "__main__":
    main(tyro.cli(Args))
