"""Train states in checkpoints: save, restore (with or without the replay buffer), commit, copy.

The buffer is its own checkpoint item so it can be left out (`save_buffer=False`).
"""

from __future__ import annotations

import sys
import time
from typing import Any

import jax
import jax.numpy as jnp

from sirl_jax.run.checkpoint import Checkpointer, CheckpointError


def commit(state: Any) -> Any:
    """Commits every leaf to the default device.

    A fresh `init` output is uncommitted and a restored one committed; jit compiles one program
    per kind, so both paths commit to share one compiled (and cached) train step.
    """
    return jax.device_put(state, jax.devices()[0])


def copy_state(state: Any) -> Any:
    """A device copy of `state` (jit it): the pre-chunk backup a donated step cannot keep."""
    return jax.tree.map(jnp.copy, state)


def save_state(ckpt: Checkpointer, state: Any, save_buffer: bool) -> int:
    """Saves `state` as checkpoint `state.env_steps` (no-op if it exists); returns the step."""
    step, updates = (int(x) for x in jax.device_get((state.env_steps, state.updates)))
    if step not in ckpt.steps():
        items = {"state": state.replace(buffer=None)}
        if save_buffer:
            items["buffer"] = state.buffer
        meta = {"env_steps": step, "updates": updates, "save_buffer": save_buffer,
                "time": time.time()}  # fmt: skip
        ckpt.save(step, items, meta)
    return step


def restore_state(ckpt: Checkpointer, init: Any, key: jax.Array, step: int | None = None):
    """(state, step) from checkpoint `step` (default: the latest), committed to the device.

    `init` is the train `init(key)`: only its output structure is used, unless the checkpoint
    has no buffer, when the buffer of a fresh `init(key)` (empty) is used.
    """
    steps = ckpt.steps()
    if not steps:
        raise CheckpointError(f"no checkpoint in {ckpt.directory}: nothing to resume")
    step = steps[-1] if step is None else step
    if step not in steps:
        raise CheckpointError(f"no checkpoint at env step {step}; available: {steps}")
    abstract = jax.eval_shape(init, key)
    has_buffer = "buffer" in ckpt.item_names(step)
    targets = {"state": abstract.replace(buffer=None)}
    if has_buffer:
        targets["buffer"] = abstract.buffer
    try:
        restored = ckpt.restore(targets, step)
    except CheckpointError as e:
        older = [s for s in steps if s < step]
        hint = f"; older checkpoints: {older} (--resume-step N)" if older else ""
        raise CheckpointError(f"{e}; nothing was deleted{hint}") from e
    if has_buffer:
        buffer = restored["buffer"]
    else:
        print("note: the checkpoint has no replay buffer (--no-save-buffer); resuming with an "
              "empty one", file=sys.stderr)  # fmt: skip
        buffer = jax.jit(init)(key).buffer
    return commit(restored["state"].replace(buffer=buffer)), step
