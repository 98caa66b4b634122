"""Checkpoints of any pytree: orbax-checkpoint underneath, atomic, verified, last N kept.

A checkpoint is a directory `<root>/<step>/` holding named items (each a pytree: the train
state, optionally the replay buffer) and a small JSON `meta` item. Orbax writes every step to
`<step>.orbax-checkpoint-tmp*` and renames it into place only when all items are on disk, so a
crash mid-save leaves the previous checkpoints untouched and the half-written one invisible.
After the rename we record each file's size and CRC32 in `<step>/sirl_checksums.json`; restore
checks them first, so a damaged file is named instead of silently loading garbage.

Faults: a write that fails (a full disk: ENOSPC) raises `CheckpointWriteError` in one line and
removes its own uncommitted temporary directory; the earlier checkpoints are untouched. A
damaged checkpoint raises `CheckpointDamaged`; `set_aside` renames it to `<step>.damaged` (kept,
no longer listed) so a resume can fall back to an older one. `remove_partial_writes` deletes the
temporary directories a killed writer left (only the single writer of a run may call it).

Best: `mark_best(step, value, metric)` records in `<root>/best.json` which checkpoint scored
best at evaluation; the rotation after each save keeps the newest `max_to_keep` and that one.
Nothing else here ever deletes a checkpoint.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

from sirl_jax.run.checkpoint_files import (
    BEST,
    CHECKSUMS,
    abstract_leaf,
    file_crc,
    first_line,
    flatten,
    is_disk_full,
    layout_change,
    read_best,
    scan,
)

_META = "meta"
_LAYOUT = "_leaf_names"
_SHAPES = "_leaf_shapes"
_TMP = ".orbax-checkpoint-tmp"
DAMAGED = ".damaged"

# Orbax logs every save/restore at INFO through absl; the shell reports checkpoints itself.
logging.getLogger("absl").setLevel(logging.WARNING)


class CheckpointError(RuntimeError):
    """A checkpoint is missing, damaged, or does not match the state it should restore into."""


class CheckpointDamaged(CheckpointError):
    """A checkpoint's files are missing, truncated or changed (size/CRC32), or unreadable."""


class CheckpointWriteError(CheckpointError):
    """A save failed (disk full, I/O error); the checkpoints written before are intact."""


class Checkpointer:
    """Saves and restores named pytrees under `directory`, keeping the newest `max_to_keep`.

    Items are pytrees of arrays (jax or numpy). Integer steps name the checkpoints; the shell
    uses the env-step counter.
    """

    def __init__(self, directory: str | os.PathLike, max_to_keep: int | None = 3):
        if max_to_keep is not None and max_to_keep < 1:
            raise ValueError(f"max_to_keep={max_to_keep!r} is invalid; allowed: an int >= 1, "
                             "or None to keep every checkpoint")  # fmt: skip
        self.directory, self.max_to_keep = Path(directory).absolute(), max_to_keep
        options = ocp.CheckpointManagerOptions(  # the rotation is `_rotate`'s, best kept
            max_to_keep=None, enable_async_checkpointing=False, create=True
        )
        self._manager = ocp.CheckpointManager(self.directory, options=options)

    def steps(self) -> list[int]:
        """Steps of all complete checkpoints, ascending (half-written ones are not listed)."""
        self._manager.reload()
        return sorted(self._manager.all_steps())

    def latest_step(self) -> int | None:
        steps = self.steps()
        return steps[-1] if steps else None

    def step_dir(self, step: int) -> Path:
        return self.directory / str(step)

    def item_names(self, step: int) -> list[str]:
        """Names of the pytree items stored at `step` (e.g. `state`, `buffer`)."""
        step_dir = self.step_dir(step)
        return sorted(p.name for p in step_dir.iterdir() if p.is_dir() and p.name != _META)

    def save(self, step: int, items: Mapping[str, Any], meta: Mapping | None = None) -> Path:
        """Writes `items` (name -> pytree) and `meta` (JSON-able) as checkpoint `step`.

        Blocks until the data is on disk. Raises CheckpointError if `step` already exists.
        """
        if _META in items:
            raise ValueError(f"item name {_META!r} is reserved")
        if step in self.steps():
            raise CheckpointError(f"checkpoint {self.step_dir(step)} already exists")
        args, layout, shapes = {}, {}, {}
        for item, tree in items.items():
            names, leaves, _ = flatten(tree)
            layout[item] = names
            shapes[item] = [list(np.shape(x)) for x in leaves]
            flat = {n: leaf for n, leaf in zip(names, leaves, strict=True) if np.size(leaf)}
            args[item] = ocp.args.StandardSave(flat)
        args[_META] = ocp.args.JsonSave({**dict(meta or {}), _LAYOUT: layout, _SHAPES: shapes})
        try:
            self._manager.save(step, args=ocp.args.Composite(**args), force=True)
            self._manager.wait_until_finished()
        except (ValueError, TypeError, OSError) as e:
            self._remove_tmp(step)
            raise self._write_error(step, "", e) from e
        step_dir = self.step_dir(step)
        tmp = step_dir / (CHECKSUMS + ".tmp")
        try:
            tmp.write_text(json.dumps(scan(step_dir), indent=0))
            os.replace(tmp, step_dir / CHECKSUMS)
        except OSError as e:
            tmp.unlink(missing_ok=True)
            raise self._write_error(step, " (the checkpoint is complete, its checksums are not)",
                                    e) from e  # fmt: skip
        self._rotate()
        return step_dir

    def _rotate(self) -> None:
        """Deletes the complete checkpoints older than the newest `max_to_keep`, except the
        best one (`best`)."""
        steps = self.steps()
        if self.max_to_keep is None or len(steps) <= self.max_to_keep:
            return
        best = self.best()
        keep = set(steps[-self.max_to_keep:]) | ({best["step"]} if best else set())
        for step in steps:
            if step not in keep:
                self._manager.delete(step)

    def mark_best(self, step: int, value: float, metric: str) -> None:
        """Records checkpoint `step` (which must exist) as the best at evaluation: `metric`
        scored `value` there. It is kept past `max_to_keep` until another is marked."""
        if step not in self.steps():
            raise CheckpointError(f"cannot mark env step {step} best: no checkpoint there")
        tmp = self.directory / (BEST + ".tmp")
        tmp.write_text(json.dumps({"step": step, "value": value, "metric": metric}))
        os.replace(tmp, self.directory / BEST)
        self._rotate()

    def best(self) -> dict | None:
        """The checkpoint marked best (`checkpoint_files.read_best`), or None."""
        return read_best(self.directory)

    def _write_error(self, step: int, what: str, e: BaseException) -> CheckpointWriteError:
        earlier = [s for s in self.steps() if s != step]
        kept = f"the newest intact checkpoint is {earlier[-1]}" if earlier else "no earlier one"
        why = "disk full (ENOSPC)" if is_disk_full(e) else first_line(e)
        return CheckpointWriteError(
            f"could not write checkpoint {self.step_dir(step)}{what}: {why}; {kept}"
        )

    def _remove_tmp(self, step: int, patience_s: float = 5.0) -> None:
        """Deletes the failed save's temporary directories. Orbax's writer threads can still
        be closing files in them after the save raised (seen on a loaded machine: a directory
        left behind), so it deletes again until none is left or `patience_s` has passed."""
        deadline = time.monotonic() + patience_s
        while True:
            paths = list(self.directory.glob(f"{step}{_TMP}*"))
            for path in paths:
                shutil.rmtree(path, ignore_errors=True)
            if not any(p.exists() for p in paths) or time.monotonic() > deadline:
                return
            time.sleep(0.1)

    def partial_writes(self) -> list[Path]:
        """Temporary directories of saves that never finished (a killed writer's)."""
        return sorted(p for p in self.directory.glob(f"*{_TMP}*") if p.is_dir())

    def remove_partial_writes(self) -> list[Path]:
        """Deletes `partial_writes()` (never a complete checkpoint); returns what it removed.

        Only the one process writing this directory may call it: another writer's save in
        progress looks the same.
        """
        gone = self.partial_writes()
        for path in gone:
            shutil.rmtree(path, ignore_errors=True)
        return gone

    def set_aside(self, step: int) -> Path:
        """Renames checkpoint `step` to `<step>.damaged` (or `.damaged2`, ...): kept on disk,
        no longer listed or restored. Returns the new path."""
        src = self.step_dir(step)
        dst, n = src.with_name(src.name + DAMAGED), 1
        while dst.exists():
            n += 1
            dst = src.with_name(f"{src.name}{DAMAGED}{n}")
        src.rename(dst)
        self._manager.reload()
        return dst

    def verify(self, step: int) -> None:
        """Raises CheckpointError naming the first file whose size or CRC32 changed."""
        step_dir = self.step_dir(step)
        if not step_dir.is_dir():
            raise CheckpointError(f"no checkpoint at {step_dir}")
        record = step_dir / CHECKSUMS
        if not record.exists():
            return  # written by an older version, or the process died right after the rename
        try:
            expected = json.loads(record.read_text())
        except (OSError, ValueError) as e:
            raise CheckpointDamaged(f"{record} is unreadable ({e})") from e
        for rel, (size, crc) in expected.items():
            path = step_dir / rel
            if not path.is_file():
                raise CheckpointDamaged(f"checkpoint file {path} is missing")
            if path.stat().st_size != size or file_crc(path) != crc:
                raise CheckpointDamaged(f"checkpoint file {path} is damaged (size/CRC32 changed)")

    def _read_meta(self, step: int) -> dict:
        try:
            restored = self._manager.restore(
                step, args=ocp.args.Composite(**{_META: ocp.args.JsonRestore()})
            )
        except Exception as e:  # orbax raises json, key and value errors alike
            raise CheckpointDamaged(
                f"checkpoint {self.step_dir(step)}: metadata unreadable ({first_line(e)})"
            ) from e
        return dict(restored[_META])

    def meta(self, step: int) -> dict:
        """The JSON metadata saved with `step`."""
        meta = self._read_meta(step)
        meta.pop(_LAYOUT, None)
        meta.pop(_SHAPES, None)
        return meta

    def leaf_shapes(self, step: int, item: str) -> dict[str, tuple[int, ...]]:
        """Leaf name (without its index) -> saved shape, for one item of checkpoint `step`."""
        meta = self._read_meta(step)
        names, shapes = meta.get(_LAYOUT, {}).get(item, []), meta.get(_SHAPES, {}).get(item, [])
        return {n.split("_", 1)[1]: tuple(s) for n, s in zip(names, shapes, strict=False)}

    def restore(self, targets: Mapping[str, Any], step: int | None = None) -> dict[str, Any]:
        """Restores items of checkpoint `step` (default: latest) into the shapes of `targets`.

        Args:
          targets: name -> pytree of arrays or `jax.ShapeDtypeStruct`s with the structure,
            shapes and dtypes to restore (e.g. `jax.eval_shape(train.init, key)`).
          step: which checkpoint; None for the latest.

        Returns:
          name -> restored pytree (jax arrays), plus `meta` (a dict).

        Raises:
          CheckpointError: no checkpoint, a damaged file (named), or a structure mismatch.
        """
        if step is None:
            step = self.latest_step()
            if step is None:
                raise CheckpointError(f"no checkpoint in {self.directory}")
        self.verify(step)
        step_dir = self.step_dir(step)
        meta = self._read_meta(step)
        layout, saved_shapes = meta.pop(_LAYOUT, {}), meta.pop(_SHAPES, {})
        args, flats = {}, {}
        for item, tree in targets.items():
            names, leaves, treedef = flatten(tree)
            saved = layout.get(item)
            if saved is not None and saved != names:
                raise CheckpointError(
                    f"checkpoint {step_dir} item {item!r} was saved by other code: "
                    f"{layout_change(saved, names)}"
                )
            for name, old, x in zip(names, saved_shapes.get(item, []), leaves, strict=False):
                if tuple(old) != tuple(np.shape(x)):
                    raise CheckpointError(
                        f"checkpoint {step_dir} item {item!r} is unreadable by this config: "
                        f"{name.split('_', 1)[1]} has shape {tuple(old)}, this config needs "
                        f"{tuple(np.shape(x))} (saved by another config or other code)"
                    )
            flats[item] = (names, leaves, treedef)
            args[item] = ocp.args.StandardRestore(
                {n: abstract_leaf(x) for n, x in zip(names, leaves, strict=True) if np.size(x)}
            )
        try:
            restored = self._manager.restore(step, args=ocp.args.Composite(**args))
        except Exception as e:  # orbax/tensorstore raise many types; all mean "unreadable"
            raise CheckpointDamaged(
                f"checkpoint {step_dir} is unreadable ({type(e).__name__}: {first_line(e)})"
            ) from e
        out: dict[str, Any] = {_META: meta}
        for item, (names, leaves, treedef) in flats.items():
            values = [
                restored[item][n] if np.size(x) else jnp.zeros(np.shape(x), x.dtype)
                for n, x in zip(names, leaves, strict=True)
            ]
            out[item] = jax.tree_util.tree_unflatten(treedef, values)
        return out

    def close(self) -> None:
        self._manager.close()
