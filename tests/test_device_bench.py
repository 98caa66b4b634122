"""experiments/bench/device.py: `--quick` prints and writes every row of the device table."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from experiments.bench import device

ROOT = Path(__file__).resolve().parents[1]


def _is_reason(row: dict) -> bool:
    """Only a Warp row may lack a figure in --quick, and only because warp-lang is missing."""
    return "impl=warp" in row["row"] and row["value"] == "not installed"


@pytest.mark.slow  # 3.4 min: every row of the table once, at --quick
@pytest.mark.timeout(1200)
def test_quick_run_has_every_row_with_a_positive_figure(tmp_path):
    out = tmp_path / "device.json"
    # run as a file from elsewhere, as on the GPU machine (no `make`, no install)
    cmd = [sys.executable, str(ROOT / "experiments" / "bench" / "device.py"), "--quick",
           "--json", str(out)]  # fmt: skip
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1100)
    assert proc.returncode == 0, proc.stderr[-3000:]
    table = json.loads(out.read_text())
    names = device.row_names(device.Sizes.quick())
    assert [r["row"] for r in table["rows"]] == names
    for row in table["rows"]:
        value = row["value"]
        if isinstance(value, str):
            assert _is_reason(row), row
        else:
            assert math.isfinite(value) and value > 0, row
    for name in names:
        assert f"| {name} |" in proc.stdout


def test_warp_rows_without_warp_lang_say_not_installed(tmp_path):
    sizes = device.Sizes.quick()
    table = device.Table(device.row_names(sizes), str(tmp_path / "t.json"), {})
    bench = device.Bench(sizes, table, budget=60.0)
    bench.env("warp", 1, "warp-lang is not installed (No module named 'warp'); pip install ...")
    bench.env("warp", 3, "Warp runs on a CUDA GPU or the CPU, and the JAX default backend is 'tpu'")
    rows = {r["row"]: r["value"] for r in json.loads((tmp_path / "t.json").read_text())["rows"]}
    assert rows["env pendulum impl=warp E=1"] == "not installed"
    assert rows["env pendulum impl=warp E=3"].startswith("n/a: Warp runs on a CUDA GPU")


def test_a_row_past_the_budget_or_failing_says_so(tmp_path):
    sizes = device.Sizes.quick()
    table = device.Table(device.row_names(sizes), None, {})
    late = device.Bench(sizes, table, budget=-1.0)
    late.run("matmul float32", lambda: (1.0, "TFLOP/s", ""))
    assert table.rows["matmul float32"]["value"].startswith("n/a: over the -1 s budget")
    bench = device.Bench(sizes, table, budget=60.0)
    bench.run("agent update", lambda: 1 / 0)
    assert table.rows["agent update"]["value"] == "n/a: error: ZeroDivisionError: division by zero"
    bench.run("agent plan E=1", lambda: (math.nan, "ms/call", ""))
    assert table.rows["agent plan E=1"]["value"] == "n/a: measured nan"
    with pytest.raises(KeyError):
        table.set("no such row", 1.0)


def test_gpu_presets_are_the_two_settings_of_the_table():
    from sirl_jax.presets import get_preset

    gpu, fast = get_preset("gpu"), get_preset("gpu-fast")
    paper, throughput = device.Sizes().settings
    assert (gpu.agent.model_size, gpu.agent.num_samples, gpu.agent.iterations) == ("5M", 512, 6)
    assert gpu.train.task == "h1hand-walk-v0" and gpu.train.impl == "jax"
    assert (gpu.train.num_envs, gpu.train.utd) == paper[1:]
    assert (fast.train.num_envs, fast.train.utd) == throughput[1:]
    assert fast.agent == gpu.agent


@pytest.mark.timeout(300)
def test_rows_runs_only_the_chosen_groups_and_agent_brings_matmul(tmp_path):
    out = tmp_path / "rows.json"
    device.main(["--quick", "--rows", "agent", "--json", str(out)])
    rows = {r["row"]: r for r in json.loads(out.read_text())["rows"]}
    assert rows["matmul float32"]["value"] > 0  # run because the agent rows divide by it
    agent = [name for name in rows if name.startswith("agent ")]
    assert len(agent) == 3
    for name in agent:
        assert rows[name]["value"] > 0 and "nanx" not in rows[name]["note"], rows[name]
    others = [r for name, r in rows.items() if not name.startswith(("agent ", "matmul"))]
    assert others and all(r["value"] == "n/a: not reached" for r in others)
