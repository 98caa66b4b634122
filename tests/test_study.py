"""experiments.study: every committed study is its spec, the seeds' keys are the old drivers',
and an arm trains as a sweep that evaluates, stops, resumes and keeps its clocks."""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pytest

from experiments.studies import specs
from experiments.studies.curves import eval_curves, eval_rows, train_rows
from experiments.studies.specs import STUDIES, Study, override
from experiments.study import arm_config, run_arm, study_of
from sirl_jax.presets import get_preset
from sirl_jax.run.runlog import load_config
from sirl_jax.sweep import Sweep, SweepError

RESULTS = Path(__file__).parents[1] / "docs" / "results"
COMMITTED = {  # a committed arm's folder -> (study, arm) that reproduces it
    "parallel_learner/beta0": ("parallel_learner", "beta0"),
    "parallel_learner/beta1": ("parallel_learner", "beta1"),
    "sit_simple_solved/transition/beta0/seed0": ("sit_simple_solved", "beta0"),
    "sit_simple_solved/transition/beta1/seed0": ("sit_simple_solved", "beta1"),
    "sit_simple_solved/transition/beta1/seed1": ("sit_simple_solved", "beta1"),
    "sit_simple_solved/transition/beta1/seed2": ("sit_simple_solved", "beta1"),
    "sit_simple_study/study/tdmpc2": ("sit_simple", "tdmpc2"),
    "sit_simple_study/study/tdmpbc": ("sit_simple", "tdmpbc"),
    "sit_simple_study/study200k/tdmpc2": ("sit_simple_hb", "tdmpc2"),
    "sit_simple_study/study200k/tdmpbc": ("sit_simple_hb", "tdmpbc"),
    "sit_simple_study/pilot/e8-utd025": ("sit_simple_pilot", "e8-utd025"),
    "sit_simple_study/pilot/e4-utd1": ("sit_simple_pilot", "e4-utd1"),
}


@pytest.mark.parametrize("folder", sorted(COMMITTED))
def test_every_committed_arm_is_the_config_of_its_spec(folder):
    """The config.json each committed arm saved (an old one reads as the run it was,
    `runlog.load_config`) is the config its spec's arm builds, field for field."""
    study, arm = COMMITTED[folder]
    assert load_config(RESULTS / folder) == arm_config(study_of(study), arm)


def test_the_seeds_keys_are_the_old_drivers():
    """split(PRNGKey(0), S)[i] for seed i, in one program or alone (`Sweep.split`), as the
    drivers before sweeps drew them, so that the committed runs reproduce."""
    config = arm_config(study_of("sit_simple_solved"), "beta1")
    legacy = jax.random.split(jax.random.PRNGKey(0), 3)
    np.testing.assert_array_equal(Sweep(seeds=3, split=3).keys(config), legacy)
    for i in range(3):
        alone = Sweep(seeds=1, first_seed=i, split=3)
        np.testing.assert_array_equal(alone.keys(config), legacy[i : i + 1])
        assert alone.names() == [f"seed={i}"] and alone.configs(config)[0].train.seed == i
    # the CLI's sweep keeps a run alone's key, PRNGKey(train.seed)
    np.testing.assert_array_equal(Sweep(seeds=2).keys(config)[1], jax.random.PRNGKey(1))
    with pytest.raises(SweepError, match="seeds 2..3 are invalid with split=3"):
        Sweep(seeds=2, first_seed=2, split=3)


def test_the_specs_the_paper_scales_and_bad_names():
    paper = arm_config(study_of("paper_table_paper"), "TDMPBC", task="hurdle")
    assert paper.train.task == "h1hand-hurdle-v0" and paper.agent.model_size == "5M"
    assert paper.agent.entropy_form == "v1" and paper.train.steps == 2_000_000
    assert paper.agent.sirl.beta == 1.0
    cpu = arm_config(study_of("paper_g_cpu"), "G=R_target", task="walk", steps=40_000)
    assert cpu.train.task == "h1-walk-v0" and cpu.agent.sirl.g_source == "target"
    assert (cpu.train.steps, cpu.train.buffer_size, cpu.train.num_envs) == (40_000, 40_000, 4)
    assert [a.agent.sirl.beta for a in (arm_config(study_of("paper_beta_cpu"), arm)
                                        for arm in ("beta=0.5", "beta=2"))] == [0.5, 2.0]
    humanoid, table = study_of("humanoid_study"), study_of("paper_table_cpu")
    assert humanoid.config("stand") == table.config("stand")
    with pytest.raises(SystemExit, match=r"agent.sirl.betta is not a config field \('betta' is not "
                       r"one of SirlConfig's: .*beta"):
        override(paper, {"agent.sirl.betta": 1.0})
    assert "sit_simple_solved" in specs.STUDIES and len(STUDIES) >= 12


def _smoke_study(budget: float | None = None) -> Study:
    cfg = get_preset("fasttd3-smoke")
    cfg = override(cfg, {"train.steps": 1_200, "train.eval_every": 400,
                         "train.checkpoint_every": 400, "train.eval_episodes": 2,
                         "train.log_every": 200})  # fmt: skip
    return Study("smoke", lambda task: override(cfg, {"train.task": task}),
                 {"beta0": {specs.BETA: 0.0}, "beta1": {specs.BETA: 1.0}}, task=cfg.train.task,
                 seeds=2, budget_cpu_s=budget)  # fmt: skip


@pytest.mark.slow  # 66 s cold: three driver calls (the sweep's resume is in test_sweep_cli)
@pytest.mark.timeout(900)
def test_an_arm_evaluates_stops_resumes_and_keeps_its_clocks(tmp_path):
    study = _smoke_study()
    config = arm_config(study, "beta1")
    out = run_arm(study, config, tmp_path / "beta1", until=400)
    first = eval_rows(out)
    assert sorted({(int(r["seed"]), int(r["env_steps"])) for r in first}) == [
        (0, 0), (0, 400), (1, 0), (1, 400)]  # before training, then every eval_every
    assert all(float(r["cpu_s"]) >= 0 and float(r["wall_s"]) >= 0 for r in first)
    run_arm(study, config, out)  # resumes from 400 and goes to the end
    curves = eval_curves(out, "policy_return")
    assert list(curves) == [0, 1]
    for c in curves.values():
        assert list(c["steps"]) == [0, 400, 800, 1_200] and np.all(np.isfinite(c["return"]))
        assert np.all(np.diff(c["wall_h"]) > 0) and np.all(np.diff(c["cpu_h"]) > 0)
    steps = [int(r["env_steps"]) for r in train_rows(out) if r["seed"] == 0]
    assert steps == sorted(set(steps)) and steps[-1] == 1_200  # no row twice
    for r in first:  # the resumed run kept the rows logged before it stopped
        assert r in eval_rows(out)
    # resuming under another config is refused, naming the field
    with pytest.raises(SystemExit, match=r"cannot resume .*agent.sirl.beta"):
        run_arm(study, arm_config(study, "beta0"), out)


@pytest.mark.timeout(600)
def test_one_seed_alone_and_the_cpu_budget(tmp_path):
    study = _smoke_study(budget=2.0)
    config = arm_config(study, "beta0")
    with pytest.raises(SystemExit, match="--seed 2 is invalid; allowed: 0..1"):
        run_arm(study, config, tmp_path / "beta0", seed=2)
    out = run_arm(study, config, tmp_path / "beta0", seed=1)
    assert out == tmp_path / "beta0" / "seed1" and (out / "seed=1" / "eval.csv").is_file()
    (curve,) = eval_curves(tmp_path / "beta0", "policy_return").values()
    # a budget the first chunk (its compile) spends: evaluated and saved there, not run on
    chunk = config.train.num_envs * config.train.chunk_steps
    assert list(curve["steps"]) == [0, chunk]
    assert list(eval_curves(tmp_path / "beta0", "policy_return")) == [1]
