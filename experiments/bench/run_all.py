"""Runs every benchmark in this folder, one after another, in fresh processes.

    make bench                      # all of them
    make bench ARGS="agent robot"   # a subset, by name (bench_<name>.py)

Each benchmark prints its own table; timings are only comparable within one run on one machine.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str]) -> int:
    available = sorted(p.stem.removeprefix("bench_") for p in HERE.glob("bench_*.py"))
    names = argv or available
    unknown = [n for n in names if n not in available]
    if unknown:
        print(f"unknown benchmark(s) {unknown}; available: {available}", file=sys.stderr)
        return 2
    status = 0
    for name in names:
        print(f"\n=== bench_{name} ===", flush=True)
        cmd = [sys.executable, "-m", f"experiments.bench.bench_{name}"]
        status |= subprocess.call(cmd, cwd=HERE.parent.parent)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
