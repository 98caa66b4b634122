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

Nothing here ever deletes a checkpoint except orbax's own `max_to_keep` rotation on save.
"""

from __future__ import annotations

import errno
import itertools
import json
import logging
import os
import re
import shutil
import time
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

CHECKSUMS = "sirl_checksums.json"
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


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0][:300] if text else type(e).__name__


def _is_disk_full(e: BaseException) -> bool:
    text = str(e)
    return (getattr(e, "errno", None) == errno.ENOSPC or "No space left on device" in text
            or "os_error_code='28'" in text)  # fmt: skip


def _file_crc(path: Path) -> int:
    crc = 0
    with open(path, "rb") as f:
        while chunk := f.read(1 << 22):
            crc = zlib.crc32(chunk, crc)
    return crc


def _scan(step_dir: Path) -> dict[str, list[int]]:
    """{relative path: [size, crc32]} of every file under a step directory."""
    out = {}
    for path in sorted(step_dir.rglob("*")):
        if path.is_file() and path.name != CHECKSUMS:
            out[str(path.relative_to(step_dir))] = [path.stat().st_size, _file_crc(path)]
    return out


def _flatten(tree: Any) -> tuple[list[str], list[Any], Any]:
    """Leaf names `0007_agent_params_encoder_0_kernel`, leaves, treedef of a pytree.

    Items are stored as flat {name: array} dicts: orbax cannot store zero-size arrays (MJX
    data has some) and a flat dict restores into any pytree type, custom nodes included.
    """
    path_leaves, treedef = jax.tree_util.tree_flatten_with_path(tree)
    names = [
        f"{i:04d}_{re.sub(r'[^A-Za-z0-9_]+', '_', jax.tree_util.keystr(path)).strip('_')}"
        for i, (path, _) in enumerate(path_leaves)
    ]
    return names, [leaf for _, leaf in path_leaves], treedef


def _layout_change(saved: list[str], expected: list[str]) -> str:
    """Names the fields that differ between a saved and an expected leaf layout."""
    strip = lambda names: [n.split("_", 1)[1] if "_" in n else n for n in names]
    old, new = strip(saved), strip(expected)
    gone, added = [n for n in old if n not in new], [n for n in new if n not in old]
    if gone or added:
        parts = []
        if gone:
            parts.append(f"it has {', '.join(gone[:5])}, which this version no longer stores")
        if added:
            parts.append(f"it lacks {', '.join(added[:5])}, which this version needs")
        return "; ".join(parts)
    pairs = itertools.zip_longest(saved, expected, fillvalue="(nothing)")
    diff = next((a, b) for a, b in pairs if a != b)
    return f"saved {diff[0]!r} where {diff[1]!r} is expected"


def _abstract_leaf(x: Any) -> jax.ShapeDtypeStruct:
    """A ShapeDtypeStruct with a sharding (orbax needs one) for an array or abstract array."""
    sharding = getattr(x, "sharding", None) or jax.sharding.SingleDeviceSharding(jax.devices()[0])
    return jax.ShapeDtypeStruct(np.shape(x), x.dtype, sharding=sharding)


def complete_steps(directory: Path) -> list[int]:
    """Steps of the complete checkpoints under `directory` (a `<step>/` holding the checksum
    file, written last), ascending; read from the directory alone, nothing created."""
    if not directory.is_dir():
        return []
    return sorted(int(p.name) for p in directory.iterdir()
                  if p.name.isdigit() and (p / CHECKSUMS).is_file())  # fmt: skip


class Checkpointer:
    """Saves and restores named pytrees under `directory`, keeping the newest `max_to_keep`.

    Items are pytrees of arrays (jax or numpy). Integer steps name the checkpoints; the shell
    uses the env-step counter.
    """

    def __init__(self, directory: str | os.PathLike, max_to_keep: int | None = 3):
        if max_to_keep is not None and max_to_keep < 1:
            raise ValueError(f"max_to_keep={max_to_keep!r} is invalid; allowed: an int >= 1, "
                             "or None to keep every checkpoint")  # fmt: skip
        self.directory = Path(directory).absolute()
        options = ocp.CheckpointManagerOptions(
            max_to_keep=max_to_keep, enable_async_checkpointing=False, create=True
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
            names, leaves, _ = _flatten(tree)
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
            tmp.write_text(json.dumps(_scan(step_dir), indent=0))
            os.replace(tmp, step_dir / CHECKSUMS)
        except OSError as e:
            tmp.unlink(missing_ok=True)
            raise self._write_error(step, " (the checkpoint is complete, its checksums are not)",
                                    e) from e  # fmt: skip
        return step_dir

    def _write_error(self, step: int, what: str, e: BaseException) -> CheckpointWriteError:
        earlier = [s for s in self.steps() if s != step]
        kept = f"the newest intact checkpoint is {earlier[-1]}" if earlier else "no earlier one"
        why = "disk full (ENOSPC)" if _is_disk_full(e) else _first_line(e)
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
            if path.stat().st_size != size or _file_crc(path) != crc:
                raise CheckpointDamaged(f"checkpoint file {path} is damaged (size/CRC32 changed)")

    def _read_meta(self, step: int) -> dict:
        try:
            restored = self._manager.restore(
                step, args=ocp.args.Composite(**{_META: ocp.args.JsonRestore()})
            )
        except Exception as e:  # orbax raises json, key and value errors alike
            raise CheckpointDamaged(
                f"checkpoint {self.step_dir(step)}: metadata unreadable ({_first_line(e)})"
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
            names, leaves, treedef = _flatten(tree)
            saved = layout.get(item)
            if saved is not None and saved != names:
                raise CheckpointError(
                    f"checkpoint {step_dir} item {item!r} was saved by other code: "
                    f"{_layout_change(saved, names)}"
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
                {n: _abstract_leaf(x) for n, x in zip(names, leaves, strict=True) if np.size(x)}
            )
        try:
            restored = self._manager.restore(step, args=ocp.args.Composite(**args))
        except Exception as e:  # orbax/tensorstore raise many types; all mean "unreadable"
            raise CheckpointDamaged(
                f"checkpoint {step_dir} is unreadable ({type(e).__name__}: {_first_line(e)})"
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
