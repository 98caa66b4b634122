"""A config's env options (`TrainConfig.env_options`: hb_compat, contact_set, hand_floor,
contact_budget) reach the env every entry point builds, not only the CLI's: the studies' arms
(`experiments.study`, through the sweep's `runner.build`) and
sim2sim's MJX reference env (the exported run's config). The sit_simple study once ran with
the task's defaults while its config.json recorded the reduced contact set."""

from __future__ import annotations

import dataclasses
import json

import mujoco
import pytest

from experiments.studies.specs import STUDY_ENV
from experiments.study import arm_config, study_of
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import h1
from sirl_jax.run.runner import load_task
from sirl_jax.run.sim2sim import _env_options


def config(study: str = "sit_simple", arm: str = "tdmpc2") -> Config:
    return arm_config(study_of(study), arm)


def arm_env(config: Config):
    """The env the study's sweep trains on (`sweep_run`'s `runner.build` loads it so)."""
    return load_task(config.train.task, **config.train.env_options)[1]


def _hands_on_floor(m: mujoco.MjModel) -> int:
    """How many hand colliders pair with the floor (MuJoCo's contype/conaffinity rule)."""
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    n = 0
    for name in h1.GEOM_GROUPS["hands"]:
        g = m.geom(name).id
        n += bool((m.geom_contype[floor] & m.geom_conaffinity[g])
                  or (m.geom_contype[g] & m.geom_conaffinity[floor]))  # fmt: skip
    return n


def _budget(m: mujoco.MjModel) -> int:
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, "max_contact_points")
    return 0 if i < 0 else int(m.numeric_data[m.numeric_adr[i]])


@pytest.mark.timeout(300)
def test_a_study_arm_builds_the_env_its_config_names():
    """The study config's options (hands off the floor, no contact budget) reach the arm's env;
    the same config with the task's defaults gives HumanoidBench's: all 62 hand colliders on the
    floor and the locomotion budget of 64."""
    study = config()
    assert {k: study.train.env_options[k] for k in STUDY_ENV} == STUDY_ENV
    m = arm_env(study).mj_model
    assert (_hands_on_floor(m), _budget(m)) == (0, 0)
    defaults = dataclasses.replace(study, train=dataclasses.replace(
        study.train, hand_floor=TrainConfig.hand_floor, contact_set=TrainConfig.contact_set,
        contact_budget=TrainConfig.contact_budget))  # fmt: skip
    m = arm_env(defaults).mj_model
    assert (_hands_on_floor(m), _budget(m)) == (62, 64)


def test_sim2sim_reference_env_takes_the_exported_runs_options(tmp_path):
    cfg = Config(train=TrainConfig(task="h1hand-sit_simple-v0", hand_floor="none",
                                   contact_set="reduced", contact_budget=0))  # fmt: skip
    (tmp_path / "config.json").write_text(json.dumps(dataclasses.asdict(cfg)))
    options = _env_options(tmp_path, {"training": {"config_file": "config.json"}})
    assert options == cfg.train.env_options
    assert options["hand_floor"] == "none" and options["contact_budget"] == 0
    # an export without a training config (sim2sim --task) takes the task's defaults
    assert _env_options(tmp_path, {"training": None}) == {}


def test_the_study_envs():
    """sit_simple is the 100k study's env, sit_simple_hb the task's defaults; a study or arm
    that does not exist is named with what does."""
    hb = config("sit_simple_hb", "tdmpbc").train
    assert hb.env_options == Config(train=TrainConfig(task=hb.task)).train.env_options
    r = config("sit_simple", "tdmpbc").train
    assert (r.hand_floor, r.contact_set, r.contact_budget) == ("none", "reduced", 0)
    with pytest.raises(SystemExit, match="study 'bogus' is unknown; allowed: sit_simple_solved"):
        study_of("bogus")
    with pytest.raises(SystemExit, match="--arm 'beta2' is unknown; allowed: tdmpc2, tdmpbc"):
        config("sit_simple", "beta2")


def test_an_arm_resumes_only_under_the_config_it_was_trained_with(tmp_path):
    """The 100k study's own config.json (saved before the env options existed, so it reads as
    the reduced env it ran on) resumes under --env-set reduced and at more steps; under hb the
    resume is refused, naming each changed option."""
    import shutil
    from pathlib import Path

    from sirl_jax.run.config_rules import check_resume
    from sirl_jax.run.runlog import load_config

    def check_resume_config(d, cfg, label):  # as `experiments.study.run_arm` checks a resume
        try:
            check_resume(load_config(d), cfg)
        except ValueError as e:
            raise SystemExit(f"error: {label}: {e}") from None

    saved = Path(__file__).parent.parent / "docs/results/sit_simple_study/study/tdmpc2/config.json"
    shutil.copy(saved, tmp_path / "config.json")
    study = study_of("sit_simple")
    check_resume_config(tmp_path, arm_config(study, "tdmpc2"), "arm")
    longer = arm_config(study, "tdmpc2")
    longer = dataclasses.replace(longer, train=dataclasses.replace(longer.train, steps=200_000))
    check_resume_config(tmp_path, longer, "arm")
    with pytest.raises(SystemExit) as e:
        hb = arm_config(study_of("sit_simple_hb"), "tdmpc2")
        hb = dataclasses.replace(hb, train=dataclasses.replace(hb.train, steps=100_000,
                                                               buffer_size=100_000))
        check_resume_config(tmp_path, hb, "arm")
    msg = str(e.value)
    for part in ("train.contact_set (saved 'reduced', given 'hb')",
                 "train.hand_floor (saved 'none', given 'all')",
                 "train.contact_budget (saved 0, given -1)"):  # fmt: skip
        assert part in msg, msg
    with pytest.raises(SystemExit, match=r"agent.sirl.beta \(saved 0.0, given 1.0\)"):
        check_resume_config(tmp_path, arm_config(study, "tdmpbc"), "arm")
