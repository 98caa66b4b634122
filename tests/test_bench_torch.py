"""experiments/bench: bench_torch's input errors, and `make bench` leaving it out."""

import subprocess
import sys
from pathlib import Path

import pytest

from experiments.bench import run_all

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.timeout(120)
def test_bad_checkout_is_named_before_any_work(tmp_path):
    missing = tmp_path / "not-a-checkout"
    cmd = [sys.executable, "-m", "experiments.bench.bench_torch", "--checkout", str(missing),
           "--python", sys.executable]  # fmt: skip
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=100)
    assert proc.returncode != 0
    assert str(missing) in proc.stderr and "tdmpc2/tdmpc2.py" in proc.stderr


@pytest.mark.timeout(60)
def test_run_all_leaves_out_the_benchmark_that_needs_a_checkout(capsys, monkeypatch):
    ran = []
    monkeypatch.setattr(run_all.subprocess, "call", lambda cmd, cwd: ran.append(cmd[-1]) or 0)
    assert run_all.main([]) == 0
    assert "experiments.bench.bench_torch" not in ran
    assert "experiments.bench.bench_agent" in ran
    assert "bench_torch left out" in capsys.readouterr().out
    assert run_all.main(["torch"]) == 2  # named alone, it says what it needs
