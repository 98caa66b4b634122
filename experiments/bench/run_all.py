"""Runs every benchmark in this folder, one after another, in fresh processes.

    make bench                      # all of them
    make bench ARGS="agent robot"   # a subset, by name (bench_<name>.py)

Each benchmark prints its own table; timings are only comparable within one run on one machine.
`bench_torch` needs a checkout and a venv from outside the repository: it is left out of "all"
and runs by its own command (experiments/README.md).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXTERNAL = {"torch": "needs --checkout and --python (the official TD-MPC2 and a torch venv)"}


def main(argv: list[str]) -> int:
    available = sorted(p.stem.removeprefix("bench_") for p in HERE.glob("bench_*.py"))
    names = argv or [n for n in available if n not in EXTERNAL]
    for name in sorted(set(EXTERNAL) - set(names)):
        print(f"bench_{name} left out: it {EXTERNAL[name]}; run it by its own command")
    unknown = [n for n in names if n not in available]
    if unknown:
        print(f"unknown benchmark(s) {unknown}; available: {available}", file=sys.stderr)
        return 2
    status = 0
    for name in names:
        if name in EXTERNAL:
            print(f"bench_{name} {EXTERNAL[name]}: run python -m experiments.bench.bench_{name} "
                  "--help", file=sys.stderr)  # fmt: skip
            status |= 2
            continue
        print(f"\n=== bench_{name} ===", flush=True)
        cmd = [sys.executable, "-m", f"experiments.bench.bench_{name}"]
        status |= subprocess.call(cmd, cwd=HERE.parent.parent)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
