"""experiments/paper: one arm of vmapped seeds writes its CSVs, marks itself done and resumes."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from experiments.paper.common import final_returns, run_arm, scale_config
from sirl_jax.presets import get_preset
from sirl_jax.run.runlog import CsvLog


def test_scale_configs():
    paper = scale_config("paper", "hurdle")
    assert paper.train.task == "h1hand-hurdle-v0" and paper.agent.model_size == "5M"
    assert paper.agent.entropy_form == "v1" and paper.train.steps == 2_000_000
    cpu = scale_config("cpu", "hurdle", beta=0.0, g_source="target", steps=40_000)
    assert cpu.train.task == "h1-hurdle-v0" and cpu.agent.sirl.beta == 0.0
    assert cpu.agent.sirl.g_source == "target" and cpu.train.eval_every == 10_000
    with pytest.raises(SystemExit, match="--scale 'gpu' is invalid"):
        scale_config("gpu", "walk")


@pytest.mark.slow  # 3.4 min: two vmapped seeds of the smoke agent, 600 steps, resumed
@pytest.mark.timeout(600)
def test_run_arm_writes_resumes_and_finishes_once(tmp_path):
    cfg = get_preset("smoke")
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(
        cfg.train, steps=600, num_envs=2, chunk_steps=25, seed_steps=100, buffer_size=1_000,
        eval_every=300))  # fmt: skip
    out = tmp_path / "arm"
    first = run_arm(cfg, 2, out, "test", max_chunks=3)  # a timing probe: not marked done
    assert not (out / "done.json").exists() and first["env_steps"] == 150
    summary = run_arm(cfg, 2, out, "test")
    assert json.loads((out / "done.json").read_text()) == summary
    rows = CsvLog(out / "eval.csv").rows()
    assert sorted({int(r["env_steps"]) for r in rows}) == [0, 300, 600]
    assert sorted({int(r["seed"]) for r in rows}) == [0, 1]
    train_rows = CsvLog(out / "train.csv").rows()
    assert [int(r["env_steps"]) for r in train_rows if r["seed"] == "0"] == list(
        range(50, 601, 50))  # the probe's rows were replaced, not repeated
    final = final_returns(out)
    assert final.shape == (2,) and np.all(np.isfinite(final))
    assert run_arm(cfg, 2, out, "test") == summary  # done: nothing is rerun


@pytest.mark.timeout(300)
def test_run_arm_refuses_a_seed_index_outside_the_arm(tmp_path):
    cfg = get_preset("smoke")
    for only in ((3,), (), (1, 1), (-1,)):
        with pytest.raises(ValueError, match=r"only=.* is invalid; allowed: distinct seed indices"
                                             r" in 0\.\.2"):  # fmt: skip
            run_arm(cfg, 3, tmp_path / "arm", "test", only=only)
