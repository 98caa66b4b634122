"""Train states in checkpoints: save, restore (with or without the replay buffer), commit, copy.

The buffer is its own checkpoint item so it can be left out (`save_buffer=False`).
"""

from __future__ import annotations

import sys
import time
from typing import Any

import jax
import jax.numpy as jnp

from sirl_jax.run.checkpoint import CheckpointDamaged, Checkpointer, CheckpointError


def commit(state: Any) -> Any:
    """Commits every leaf to the default device.

    A fresh `init` output is uncommitted and a restored one committed; jit compiles one program
    per kind, so both paths commit to share one compiled (and cached) train step.
    """
    return jax.device_put(state, jax.devices()[0])


def copy_state(state: Any) -> Any:
    """A device copy of `state` (jit it): the pre-chunk backup a donated step cannot keep."""
    return jax.tree.map(jnp.copy, state)


def save_state(ckpt: Checkpointer, state: Any, save_buffer: bool,
               extra: dict | None = None) -> int:  # fmt: skip
    """Saves `state` as checkpoint `state.env_steps` (no-op if it exists); returns the step.
    `extra`: more JSON-able entries for the checkpoint's meta."""
    step, updates = (int(x) for x in jax.device_get((state.env_steps, state.updates)))
    if step not in ckpt.steps():
        items = {"state": state.replace(buffer=None)}
        if save_buffer:
            items["buffer"] = state.buffer
        meta = {"env_steps": step, "updates": updates, "save_buffer": save_buffer,
                "time": time.time(), **(extra or {})}  # fmt: skip
        ckpt.save(step, items, meta)
    return step


def restore_state(ckpt: Checkpointer, init: Any, key: jax.Array, step: int | None = None,
                  *, fall_back: bool = False):  # fmt: skip
    """(state, step) from checkpoint `step` (default: the latest), committed to the device.

    `init` is the train `init(key)`: only its output structure is used, unless the checkpoint
    has no buffer, when the buffer of a fresh `init(key)` (empty) is used.

    With `fall_back` (and `step` None), a damaged latest checkpoint does not fail the restore:
    the newest intact one is used, and the damaged newer ones are set aside (renamed
    `<step>.damaged`, kept on disk) so the resumed run can write those steps again; a note on
    stderr says so. Nothing is renamed unless an intact checkpoint was found.
    """
    steps = ckpt.steps()
    if not steps:
        raise CheckpointError(f"no checkpoint in {ckpt.directory}: nothing to resume")
    if step is not None and step not in steps:
        raise CheckpointError(f"no checkpoint at env step {step}; available: {steps}")
    candidates = [step] if step is not None else steps[::-1] if fall_back else steps[-1:]
    abstract = jax.eval_shape(init, key)
    damaged: list[tuple[int, CheckpointDamaged]] = []
    for s in candidates:
        has_buffer = "buffer" in ckpt.item_names(s)
        targets = {"state": abstract.replace(buffer=None)}
        if has_buffer:
            targets["buffer"] = abstract.buffer
        try:
            restored = ckpt.restore(targets, s)
            break
        except CheckpointDamaged as e:
            damaged.append((s, e))
        except CheckpointError as e:
            raise CheckpointError(f"{e}; nothing was deleted{_older_hint(steps, s)}") from e
    else:
        if len(damaged) == 1:
            s, e = damaged[0]
            raise CheckpointDamaged(f"{e}; nothing was deleted{_older_hint(steps, s)}") from e
        raise CheckpointDamaged(f"every checkpoint in {ckpt.directory} is damaged: "
                                + "; ".join(str(e) for _, e in damaged)
                                + "; nothing was renamed or deleted")  # fmt: skip
    for bad, e in damaged:
        moved = ckpt.set_aside(bad)
        print(f"note: {e}; it is kept as {moved} and the run resumes from the newest intact "
              f"checkpoint, env step {s:,}", file=sys.stderr)  # fmt: skip
    if has_buffer:
        buffer = restored["buffer"]
    else:
        print("note: the checkpoint has no replay buffer (--no-save-buffer); resuming with an "
              "empty one", file=sys.stderr)  # fmt: skip
        buffer = jax.jit(init)(key).buffer
    return commit(restored["state"].replace(buffer=buffer)), s


def _older_hint(steps: list[int], step: int) -> str:
    older = [s for s in steps if s < step]
    return f"; older checkpoints: {older} (--resume-step N)" if older else ""
