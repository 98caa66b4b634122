"""Every registered task's compiled MuJoCo model, fingerprinted array by array.

    .venv/bin/python -m experiments.fidelity.model_fingerprint --out before.json
    .venv/bin/python -m experiments.fidelity.model_fingerprint --out after.json \
        --against before.json

A refactor of the task code must leave every model identical: for each task id, the SHA-256 of
every numpy array of its `MjModel` (geoms, bodies, actuators, contype/conaffinity, ...) and of its
names buffer. `--against` lists each task and array that differs, and exits 1 if any does.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import tyro


def fingerprint(model) -> dict[str, str]:
    """{array name: sha256 of its dtype, shape and bytes} for every array field of `model`."""
    out = {}
    for name in sorted(dir(model)):
        if name.startswith("_"):
            continue
        try:
            value = getattr(model, name)
        except Exception:  # noqa: BLE001 - properties that need arguments or raise
            continue
        if isinstance(value, np.ndarray):
            h = hashlib.sha256(f"{value.dtype}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).tobytes())
            out[name] = h.hexdigest()[:16]
    return out


@dataclasses.dataclass(frozen=True)
class Args:
    out: str
    """Where to write {task id: {array: hash}}."""
    against: str | None = None
    """An earlier output to compare with."""


def main(args: Args) -> None:
    from sirl_jax.envs import make
    from sirl_jax.envs.registry import TASKS

    prints = {}
    for task_id in sorted(TASKS):
        env = make(task_id)
        model = getattr(env, "mj_model", None)
        if model is not None:
            prints[task_id] = fingerprint(model)
    Path(args.out).write_text(json.dumps(prints, indent=1, sort_keys=True))
    print(f"{len(prints)} models fingerprinted -> {args.out}")
    if args.against:
        before = json.loads(Path(args.against).read_text())
        diffs = [f"{t}: {'missing' if t not in prints else 'new'}"
                 for t in sorted(set(before) ^ set(prints))]  # fmt: skip
        for t in sorted(set(before) & set(prints)):
            arrays = sorted(k for k in set(before[t]) | set(prints[t])
                            if before[t].get(k) != prints[t].get(k))  # fmt: skip
            if arrays:
                diffs.append(f"{t}: {', '.join(arrays)}")
        print("\n".join(diffs) or f"all {len(prints)} models identical, array for array")
        sys.exit(1 if diffs else 0)


if __name__ == "__main__":
    main(tyro.cli(Args))
