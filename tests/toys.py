"""A toy `Train` for the shell's failure paths: a 3-float state, 10 env steps per call.

`runner.make_train` is replaced by `lambda config, env: toy`; the rest of the shell (run dir,
logs, checkpoints, resume, failure handling) runs for real on the smoke preset's pendulum.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class ToyState:
    params: jax.Array
    buffer: dict
    key: jax.Array
    env_steps: jax.Array
    updates: jax.Array


@dataclasses.dataclass(frozen=True)
class ToyBuffer:
    nbytes: int = 32

    def describe(self) -> str:
        return "toy buffer"


@dataclasses.dataclass(frozen=True)
class ToyAgent:
    iterations: int = 1


@dataclasses.dataclass(frozen=True)
class ToyTrain:
    """A `Train` stand-in: 10 env steps and one update per call.

    The chunk reaching `fail_at` (and every later one) reports a NaN loss; every chunk reports
    `blowups` physics blow-ups from `blowups_from` on; `buffer_floats` random floats make the
    checkpoints that large (incompressible), for a disk-full test.
    """

    fail_at: int = 10**9
    oom: bool = False
    blowups: int = 0
    blowups_from: int = 0
    buffer_floats: int = 8
    steps_per_call: int = 10
    buffer: ToyBuffer = ToyBuffer()
    agent: ToyAgent = ToyAgent()

    def init(self, key):
        zero = jnp.zeros((), jnp.int32)
        noise = jax.random.normal(jax.random.PRNGKey(1), (self.buffer_floats,))
        return ToyState(jnp.zeros(3), {"obs": noise}, key, zero, zero)

    def step(self, state):
        if self.oom:
            raise jax.errors.JaxRuntimeError("RESOURCE_EXHAUSTED: Out of memory allocating 8 GB")
        env_steps = state.env_steps + self.steps_per_call
        bad = env_steps >= self.fail_at
        blowups = jnp.where(env_steps >= self.blowups_from, self.blowups, 0)
        metrics = {"train/loss": jnp.where(bad, jnp.nan, 1.0), "nonfinite_loss": bad.astype(int),
                   "env/blowups": blowups, "env_steps": env_steps,
                   "updates": state.updates + 1}  # fmt: skip
        new = state.replace(
            params=state.params + jnp.where(bad, jnp.nan, 1.0),
            buffer={"obs": state.buffer["obs"] + 1.0},
            key=jax.random.split(state.key)[0],
            env_steps=env_steps,
            updates=state.updates + 1,
        )
        return new, metrics

    def evaluate(self, state, key):
        return {"eval/x": jnp.sum(state.params)}


def toy_argv(run_dir: Path, *flags: str, steps: int = 2000) -> list[str]:
    """`train` arguments for a toy run: checkpoints every 20 env steps, logs every 10."""
    return ["train", "--preset", "smoke", "--steps", str(steps), "--checkpoint-every", "20",
            "--eval-every", "0", "--log-every", "10", "--no-progress", "--no-tensorboard",
            "--run-dir", str(run_dir), *flags]  # fmt: skip
