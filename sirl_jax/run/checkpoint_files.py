"""The file-level parts of `checkpoint.py`: CRC32 scans, flat leaf names, layout diffs."""

from __future__ import annotations

import errno
import itertools
import json
import re
import zlib
from pathlib import Path
from typing import Any

import jax
import numpy as np

CHECKSUMS = "sirl_checksums.json"
BEST = "best.json"


def first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0][:300] if text else type(e).__name__


def is_disk_full(e: BaseException) -> bool:
    text = str(e)
    return (getattr(e, "errno", None) == errno.ENOSPC or "No space left on device" in text
            or "os_error_code='28'" in text)  # fmt: skip


def file_crc(path: Path) -> int:
    crc = 0
    with open(path, "rb") as f:
        while chunk := f.read(1 << 22):
            crc = zlib.crc32(chunk, crc)
    return crc


def scan(step_dir: Path) -> dict[str, list[int]]:
    """{relative path: [size, crc32]} of every file under a step directory."""
    out = {}
    for path in sorted(step_dir.rglob("*")):
        if path.is_file() and path.name != CHECKSUMS:
            out[str(path.relative_to(step_dir))] = [path.stat().st_size, file_crc(path)]
    return out


def flatten(tree: Any) -> tuple[list[str], list[Any], Any]:
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


def layout_change(saved: list[str], expected: list[str]) -> str:
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


def abstract_leaf(x: Any) -> jax.ShapeDtypeStruct:
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


def read_best(directory: Path) -> dict | None:
    """{'step', 'value', 'metric'} of the checkpoint `Checkpointer.mark_best` recorded under
    `directory`, or None when none is recorded or that checkpoint is no longer complete (set
    aside as damaged, or deleted by hand). Read from the files alone, nothing created."""
    try:
        record = json.loads((Path(directory) / BEST).read_text())
    except (OSError, ValueError):
        return None
    return record if record.get("step") in complete_steps(Path(directory)) else None
