"""The hands on the floor (`hand_floor`, sirl_jax/hb_compat.py): which hand colliders pair with
the floor under each value, a hand pushed into the floor in a constructed state (held with
"all", through it with "none"; MuJoCo C, and MJX in the slow test), and the option's checks.
And the locomotion scenes that read `contact_set`: sit_simple's seat holds a foot, a palm and
an ankle housing pushed into it with "hb" and lets them through with "reduced"."""

from __future__ import annotations

import dataclasses
import functools
import json

import mujoco
import numpy as np
import pytest
from test_contact_sets import (
    FORCE,
    GAP,
    HELD,
    MJX_TOL,
    THROUGH,
    _colliders,
    _env,
    _limp_weightless,
    _tip,
    depth,
    press_case,
    simulate,
)

from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import h1, load
from sirl_jax.run import runlog


@functools.cache
def _model(task: str, hand_floor: str) -> mujoco.MjModel:
    return load(task, hand_floor=hand_floor)[1].mj_model


def _pairs_with(m: mujoco.MjModel, a: int, b: int) -> bool:
    """MuJoCo's rule for two geoms of different bodies (no explicit pair, no exclude)."""
    return bool((m.geom_contype[a] & m.geom_conaffinity[b])
                or (m.geom_contype[b] & m.geom_conaffinity[a]))  # fmt: skip


@pytest.mark.timeout(300)
@pytest.mark.parametrize("task", ["walk", "push"])
def test_each_value_pairs_exactly_its_hand_colliders_with_the_floor(task):
    """Worked out from the compiled bits, not from the code that sets them: "all" pairs each of
    the 62 hand colliders with the floor, "palms" the 16 wrist and palm colliders, "none" none;
    and the three models differ in nothing but those colliders' conaffinity."""
    models = {v: _model(task, v) for v in ("all", "palms", "none")}
    hands = h1.GEOM_GROUPS["hands"]
    assert len(hands) == 62
    palms = {n for n in hands if n.split("_")[1].startswith(("wrist", "palm"))}
    assert len(palms) == 16
    for value, expect in (("all", set(hands)), ("palms", palms), ("none", set())):
        m = models[value]
        floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        touching = {n for n in hands if _pairs_with(m, floor, m.geom(n).id)}
        assert touching == expect, (task, value, sorted(touching ^ expect)[:4])
        assert np.array_equal(m.geom_contype, models["none"].geom_contype), value
        changed = np.nonzero(m.geom_conaffinity != models["none"].geom_conaffinity)[0]
        assert {m.geom(int(g)).name for g in changed} == expect, value


def hand_press_case(hand_floor: str):
    """(model, data, hand geoms, u, face): walk's robot limp and weightless at its keyframe,
    every collider but the left hand's switched off, the robot lowered until the hand's lowest
    point is `GAP` above the floor, `FORCE` down on the hand's palm body. `face` = the floor's
    height (0) . u, so `tip - face` is how far the hand ends below the floor."""
    m = _limp_weightless(_model("walk", hand_floor))
    hand = [m.geom(n).id for n in h1.GEOM_GROUPS["hands"] if n.startswith("lh_")]
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    for g in range(m.ngeom):
        if g not in hand and g != floor:
            m.geom_contype[g] = m.geom_conaffinity[g] = 0
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    u = np.array([0.0, 0.0, -1.0])
    lowest = -_tip(m, d.geom_xpos, d.geom_xmat, hand, u)  # height of the hand's lowest point
    d.qpos[2] -= lowest - GAP
    palm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "lh_palm")
    d.xfrc_applied[palm, :3] = FORCE * u
    mujoco.mj_forward(m, d)
    return m, d, hand, u, 0.0


def hand_depth(m, d, geoms, u, face, backend: str = "c") -> float:
    xpos, xmat = simulate(m, d, backend)
    return _tip(m, xpos, xmat, geoms, u) - face


@pytest.mark.timeout(300)
def test_hand_pushed_into_the_floor_stops_on_it_only_with_hand_floor():
    m, d, hand, u, face = hand_press_case("all")
    assert abs(-_tip(m, d.geom_xpos, d.geom_xmat, hand, u) - GAP) < 1e-9  # the start: GAP above
    held = hand_depth(m, d, hand, u, face)
    through = hand_depth(*hand_press_case("none"))
    assert held < HELD, held
    assert through > THROUGH, through


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_mjx_agrees_with_c_on_the_hand_pushed_into_the_floor():
    c = hand_depth(*hand_press_case("all"))
    j = hand_depth(*hand_press_case("all"), backend="mjx")
    assert j < HELD and abs(j - c) < MJX_TOL, (c, j)


def _seat(contact_set: str) -> int:
    """sit_simple's seat collider: the chair's collider 0.21 m wide in x."""
    m = _env("sit_simple", contact_set).mj_model
    (seat,) = [g for g in _colliders(m, "chair") if abs(m.geom_size[g][0] - 0.21) < 1e-9]
    return seat


@pytest.mark.timeout(300)
@pytest.mark.parametrize("mover", ["left_foot", "lh_palm0", "left_ankle"])
def test_sit_chair_holds_the_whole_robot_with_hb_contacts_only(mover):
    """Feet, palms and the link capsules (here the ankle housing) pushed backwards into the
    seat: HumanoidBench's chair touches them, the reduced set's does not."""
    case = {c: press_case("sit_simple", c, mover, _seat(c), (-1.0, 0.0, 0.0),
                          np.array([0.02, 0.2, 0.2])) for c in ("hb", "reduced")}  # fmt: skip
    held, through = depth(*case["hb"]), depth(*case["reduced"])
    assert held < HELD, (mover, held)
    assert through > THROUGH, (mover, through)


@pytest.mark.timeout(300)
def test_hand_floor_is_checked_and_old_runs_resume_without_it(tmp_path):
    with pytest.raises(ValueError, match=r"hand_floor.*'fingers'.*'all', 'palms', 'none'"):
        load("walk", hand_floor="fingers")
    with pytest.raises(ValueError, match=r"train.hand_floor"):
        TrainConfig(hand_floor="All")
    h1_walk = load("h1-walk-v0", hand_floor="all")[1].mj_model  # no hands: nothing to change
    assert mujoco.mj_name2id(h1_walk, mujoco.mjtObj.mjOBJ_GEOM, "lh_palm0") < 0
    saved = dataclasses.asdict(Config())
    assert saved["train"]["hand_floor"] == "all"
    del saved["train"]["hand_floor"]  # a config.json written before the option existed
    (tmp_path / "config.json").write_text(json.dumps(saved))
    assert runlog.load_config(tmp_path).train.hand_floor == "none"
    # before hand_floor, "hb" meant what is now "reduced" in the scenes that read it
    for task, contact_set in (("h1hand-sit_simple-v0", "reduced"), ("crawl", "reduced"),
                              ("h1hand-push-v0", "hb"), ("walk", "hb")):  # fmt: skip
        saved["train"].update(task=task, contact_set="hb")
        (tmp_path / "config.json").write_text(json.dumps(saved))
        assert runlog.load_config(tmp_path).train.contact_set == contact_set, task
