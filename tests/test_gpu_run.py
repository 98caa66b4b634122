"""experiments/bench/gpu_run.py at --quick: both calls run as files, as on the GPU machine, and
write every row they measure to their JSONL as they go."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _call(tmp_path: Path, *args: str) -> list[dict]:
    cmd = [sys.executable, str(ROOT / "experiments" / "bench" / "gpu_run.py"), "--quick",
           "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "cache"), *args]  # fmt: skip
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    call = args[args.index("--call") + 1]
    rows = [json.loads(line) for line in (tmp_path / "out" / f"call{call}.jsonl").open()]
    # every row was printed, with the seconds since the call began
    assert len([ln for ln in proc.stdout.splitlines() if " s  " in ln]) == len(rows)
    assert rows[0]["kind"] == "header" and rows[-1]["kind"] == "done"
    assert not [r for r in rows if r["kind"] == "error"], rows
    return rows


@pytest.mark.slow  # about 3 min: two quick calls, four compiles
@pytest.mark.timeout(1800)
def test_learning_call_evaluates_on_a_wall_clock_cadence(tmp_path):
    rows = _call(tmp_path, "--call", "1", "--train-s", "12", "--eval-every-s", "4",
                 "--betas", "1", "0")  # both arms as one sweep program
    both = [r for r in rows if r["kind"] == "eval"]
    evals = [r for r in both if r["beta"] == 1.0]
    assert [r["env_steps"] for r in both if r["beta"] == 0.0] == [r["env_steps"] for r in evals]
    assert 3 <= len(evals) <= 5  # 12 s of training, one every 4 s and one at the end
    steps = [r["env_steps"] for r in evals]
    assert steps == sorted(steps) and len(set(steps)) == len(steps)
    walls = [r["train_wall_s"] for r in evals]
    # the last evaluation comes once 12 s of wall-clock have passed since the compile, however
    # soon after another (train_wall_s leaves out the evaluations and the rows' writing, so it
    # can end under 12: 11.8 in one run)
    compiled = next(r for r in rows if r["kind"] == "compiled")
    assert evals[-1]["elapsed_s"] - compiled["elapsed_s"] >= 12.0 - 0.1  # rows round to 0.1 s
    assert all(b - a >= 3.5 for a, b in zip(walls[:-2], walls[1:-1], strict=True))
    for r in evals:
        assert math.isfinite(r["policy_return"]) and r["env_steps_per_s"] > 0
        assert r["updates_per_s"] > 0 and r["wall_s"] >= r["train_wall_s"]
    # the first evaluation at the bar, if any, is the wall-clock of the first row at it
    hit = [r for r in evals if r["policy_return"] >= rows[1]["bar"]]
    assert evals[-1]["first_bar_wall_s"] == (hit[0]["wall_s"] if hit else None)


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_cost_call_times_runs_and_round_trips_the_planner(tmp_path):
    rows = _call(tmp_path, "--call", "2")
    runs = [r for r in rows if r["kind"] == "runs"]
    assert [r["runs"] for r in runs] == [1, 2]
    for r in runs:
        total = r["env_steps_per_s_per_run"] * r["runs"]
        assert r["env_steps_per_s_total"] == pytest.approx(total, rel=1e-3, abs=0.1)
        hours = 2_000_000 / r["env_steps_per_s_per_run"] / 3600
        assert r["hours_2m_all_runs"] == pytest.approx(hours, rel=1e-2)
        assert r["device_hours_per_run"] == pytest.approx(hours / r["runs"], rel=1e-2)
    (plan,) = [r for r in rows if r["kind"] == "planner.jax"]
    assert plan["equal_within_1e_5"] and plan["bytes"] > 1000
