"""Sharding over 4 virtual CPU devices, in a subprocess under a hard timeout (device-count
flags must be set before JAX starts, and multi-device runs have hung here before).

`tests/sharding_worker.py` runs layout envs (one learner, E = 4 envs and the batch split over 4
devices) against the unsharded run; layout seeds (S = 4 seeds over 4 devices) against the
vmapped run and single-seed runs; checkpoint round trips sharded -> unsharded and back; the
one-line errors; `train --devices 4`. A second process runs layout envs after
`jax.distributed.initialize` for one process (the multi-host code path).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

WORKER = Path(__file__).parent / "sharding_worker.py"


# The module's worker compiles a sharded run on 4 simulated devices: 640 s of a fresh-clone
# `make test`, so the whole module runs in `make test-slow`.
pytestmark = pytest.mark.slow

def _worker(*flags: str) -> dict:
    env = {**os.environ, "JAX_PLATFORMS": "cpu",
           "XLA_FLAGS": "--xla_force_host_platform_device_count=4"}  # fmt: skip
    try:
        proc = subprocess.run([sys.executable, str(WORKER), *flags], env=env,
                              capture_output=True, text=True, timeout=840)  # fmt: skip
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"the sharding worker {flags} hung (killed after {e.timeout} s)")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-3000:]
    return json.loads(lines[-1][len("RESULT "):])


@pytest.fixture(scope="module")
def result():
    return _worker()


@pytest.mark.timeout(900)
def test_the_multihost_path_runs_with_one_process():
    r = _worker("--distributed")
    assert r == {"devices": 4, "processes": 1, "updates": 40}


@pytest.mark.timeout(900)
def test_envs_layout_matches_the_unsharded_run_of_the_same_global_batch(result):
    r = result["envs"]
    assert r["updates"] == [40, 40]  # the pretraining updates of chunk 2
    assert r["params_max_diff"] < 1e-5, r
    assert r["buffer_max_diff"] < 1e-5 and r["buffer_ints_equal"], r
    assert r["buffer_split"] and r["buffer_shards"] == 4, r
    assert r["params_replicated"]
    assert r["planning_chunk_updates"] == 60 and r["planning_chunk_finite"]


@pytest.mark.timeout(900)
def test_seeds_layout_gives_the_per_seed_results_of_unsharded_runs(result):
    r = result["seeds"]
    assert r["equal_to_vmapped"] and r["split"], r
    assert r["max_diff_to_single_seed_runs"] == 0.0, r


@pytest.mark.timeout(900)
def test_checkpoints_move_between_layouts(result):
    r = result["checkpoint"]
    assert r["sharded_to_unsharded"] and r["unsharded_is_single_device"]
    assert r["unsharded_to_sharded"] and r["restored_split"]


@pytest.mark.timeout(900)
def test_layout_errors_are_one_line(result):
    e = result["errors"]
    assert e["too_many_shards"] == (
        "devices=5 is invalid: this process sees 4 cpu device(s); allowed: 1..4")
    assert e["envs_not_dividing"] == (
        "train.num_envs=6 does not divide over 4 devices; allowed: a multiple of 4")
    assert e["batch_not_dividing"] == (
        "agent.batch_size=10 does not divide over 4 devices; allowed: a multiple of 4")
    assert e["seeds_not_dividing"] == (
        "seeds=6 does not divide over 4 devices; allowed: a multiple of 4")


@pytest.mark.timeout(900)
def test_train_command_with_devices(result):
    r = result["cli"]
    assert r["code"] == 0 and r["checkpoints"][-1] == 1200 and r["updates"] > 0, r
    assert r["bad_code"] == 2 and not r["bad_dir_made"]
