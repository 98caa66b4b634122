"""MJX's contact budget (`max_contact_points`, `h1.set_max_contact_points`): it changes
nothing while fewer contacts than the budget are active, and a full budget is reported."""

from __future__ import annotations

import dataclasses
import json

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from experiments.fidelity.pair_cap import active_contacts
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import control_step, h1, load, physics
from sirl_jax.envs.physics import OVERFLOW_METRIC, contact_budget, contact_profile
from sirl_jax.envs.task_parts import LOCOMOTION_BUDGET, MANIPULATION_BUDGET, budget_for
from sirl_jax.run import runlog

BOXES = 3
"""Boxes resting flat on the floor: MJX's plane-box function gives 4 contacts each (the corners),
so 12 are active at rest."""
STEPS = 60


def _boxes(budget: int) -> mujoco.MjModel:
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=(5, 5, 0.1))
    for i in range(BOXES):
        body = spec.worldbody.add_body(pos=(0.5 * i, 0.1 * i, 0.099))  # 1 mm into the floor
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=(0.1, 0.15, 0.1))
    if budget:
        h1.set_max_contact_points(spec, budget)
    return spec.compile()


def _run(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(qpos after STEPS, [STEPS] budget-full flags) from the compiled model's qpos0."""
    mx = mjx.put_model(m)
    budget = max(contact_budget(m), 1)

    def body(d, _):
        d = mjx.step(mx, d)
        return d, physics.budget_full(d, budget)

    d, full = jax.jit(lambda d: jax.lax.scan(body, d, None, length=STEPS))(mjx.make_data(mx))
    return np.asarray(d.qpos), np.asarray(full)


@pytest.mark.timeout(300)
def test_budget_changes_nothing_until_full_and_reports_a_full_one():
    free_qpos, _ = _run(_boxes(0))
    roomy_qpos, roomy_full = _run(_boxes(4 * BOXES + 4))
    np.testing.assert_allclose(roomy_qpos, free_qpos, atol=1e-6)
    assert not roomy_full.any()
    # A budget of 8 holds 8 of the 12 corners, the deepest: the left-out box sinks until its
    # corners rank first, and the three take turns, each ending over 1 mm deeper than with every
    # contact (about 1.7 mm against 0.1 mm). Every step says the budget was full.
    tight_qpos, tight_full = _run(_boxes(8))
    assert tight_full.all()
    sunk = free_qpos.reshape(BOXES, 7)[:, 2] - tight_qpos.reshape(BOXES, 7)[:, 2]
    assert sunk.min() > 1e-3, sunk
    assert active_contacts(_boxes(0), free_qpos[None])[0] == 4 * BOXES


def test_budget_is_read_reported_and_left_out_of_warps_sizes():
    assert contact_budget(_boxes(0)) == 0 and contact_budget(_boxes(8)) == 8
    assert contact_profile(_boxes(8)) == contact_profile(_boxes(0))
    with pytest.raises(ValueError, match="max_contact_points must be >= 1, got 0"):
        h1.set_max_contact_points(mujoco.MjSpec(), 0)
    _, env = load("bookshelf_simple")
    assert env.sim.contact_budget == env.task.max_contact_points > 0
    assert OVERFLOW_METRIC in env.metric_names()
    _, push = load("push")  # the manipulation tasks' shared budget
    assert push.sim.contact_budget == MANIPULATION_BUDGET and OVERFLOW_METRIC in push.metric_names()
    _, push = load("push", contact_budget=0)
    assert push.sim.contact_budget == 0 and OVERFLOW_METRIC not in push.metric_names()


@pytest.mark.timeout(300)
def test_budget_step_flags_only_a_full_budget():
    m = _boxes(4 * BOXES)  # exactly the resting contacts: full
    step = control_step.make_budget_control_step(4 * BOXES, n_substeps=5)
    mx = mjx.put_model(m)
    d, full = jax.jit(step)(mx, mjx.make_data(mx), jnp.zeros(0))
    assert float(full) == 1.0
    m = _boxes(4 * BOXES + 1)
    mx = mjx.put_model(m)
    step = control_step.make_budget_control_step(4 * BOXES + 1, n_substeps=5)
    d, full = jax.jit(step)(mx, mjx.make_data(mx), jnp.zeros(0))
    assert float(full) == 0.0


def test_budget_option_is_checked_and_old_runs_resume_without_one(tmp_path):
    assert load("bookshelf_simple", contact_budget=0)[1].sim.contact_budget == 0
    assert load("bookshelf_simple", contact_budget=40)[1].sim.contact_budget == 40
    assert load("walk", contact_budget=40)[1].sim.contact_budget == 40
    walk = load("walk")[1]  # every locomotion task has one: its hands touch the floor
    assert walk.sim.contact_budget == LOCOMOTION_BUDGET and OVERFLOW_METRIC in walk.metric_names()
    with pytest.raises(ValueError, match=r"contact_budget=-2 is invalid; allowed: -1"):
        load("push", contact_budget=-2)
    with pytest.raises(ValueError, match=r"train.contact_budget=1.5 is invalid"):
        TrainConfig(contact_budget=1.5)
    saved = dataclasses.asdict(Config())
    assert saved["train"]["contact_budget"] == -1
    del saved["train"]["contact_budget"]  # a config.json written before the option existed
    (tmp_path / "config.json").write_text(json.dumps(saved))
    assert runlog.load_config(tmp_path).train.contact_budget == 0


def test_budget_rule():
    """The smallest multiple of 32, at least 64, 20 or more above the measured maximum."""
    assert [budget_for(n) for n in (0, 43, 44, 45, 49, 76, 77, 92, 104, 109)] == [
        64, 64, 64, 96, 96, 96, 128, 128, 128, 160]
