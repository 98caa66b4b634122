"""The manipulation scenes' contact sets (`contact_set`, sirl_jax/hb_compat.py), in constructed
states: with HumanoidBench's set ("hb") a hand pressed into a table stops on it, the torso
pushed into a cabinet is held, so is the shoulder housing pushed into a table, and a book
dropped on a book rests on it; with the "reduced" set
each passes through. MuJoCo C on the model MJX compiles; the slow tests run the same states in
MJX and ask for the same outcome within `MJX_TOL`."""

from __future__ import annotations

import copy
import dataclasses
import functools
import json

import jax
import mujoco
import numpy as np
import pytest
from mujoco import mjx
from shapes import support

from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import load
from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.envs.tasks import scene
from sirl_jax.run import runlog

GAP = 0.02  # start: the moving geom this far from the fixture's face (m)
FORCE = 40.0  # N on the moving body, towards the fixture
STEPS = 150  # physics steps (0.3 s at 2 ms)
HELD = 0.005  # a held geom ends at most this far inside the fixture
THROUGH = 0.02  # one that passes ends at least this far inside
MJX_TOL = 0.005  # MJX and MuJoCo C end within this distance of each other (m)


@functools.cache
def _env(task: str, contact_set: str):
    return load(task, contact_set=contact_set)[1]


def _geom(m: mujoco.MjModel, name: str) -> int:
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
    assert g >= 0, name
    return g


def _colliders(m: mujoco.MjModel, body: str) -> list[int]:
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
    return [g for g in range(m.ngeom) if m.geom_bodyid[g] == b
            and (m.geom_contype[g] or m.geom_conaffinity[g])]  # fmt: skip


def _limp_weightless(m: mujoco.MjModel) -> mujoco.MjModel:
    m = copy.deepcopy(m)
    m.opt.gravity[:] = 0
    m.actuator_gainprm[:, 0] = 0  # position servos off: the joints move freely
    m.actuator_biasprm[:, :3] = 0
    return m


def _place_plate(m, d, fixture: int, centre, half) -> None:
    """Makes a static box a world-aligned plate of half size `half` at `centre`: the box is
    shrunk and its body moved (the body's other colliders shrunk to 1 mm). The compiled
    bounding volumes stay valid: they are the body's, in its frame, and only grow too large."""
    body = m.geom_bodyid[fixture]
    for g in _colliders(m, m.body(body).name):
        m.geom_size[g] = 1e-3
    m.geom_size[fixture] = half
    parent = m.body_parentid[body]
    rot_parent = d.xmat[parent].reshape(3, 3)
    q_world = np.zeros(4)  # body orientation that makes the geom's world frame the identity
    mujoco.mju_negQuat(q_world, m.geom_quat[fixture])
    q_parent_inv, q_body = np.zeros(4), np.zeros(4)
    mujoco.mju_negQuat(q_parent_inv, d.xquat[parent])
    mujoco.mju_mulQuat(q_body, q_parent_inv, q_world)
    m.body_quat[body] = q_body
    rot_world = np.zeros(9)
    mujoco.mju_quat2Mat(rot_world, q_world)
    origin = np.asarray(centre) - rot_world.reshape(3, 3) @ m.geom_pos[fixture]
    m.body_pos[body] = rot_parent.T @ (origin - d.xpos[parent])


def _tip(m, xpos, xmat, geoms, u) -> float:
    """The extreme point along `u` of a set of geoms."""
    return max(support(m.geom_type[g], m.geom_size[g], xpos[g], np.reshape(xmat[g], (3, 3)), u)
               for g in geoms)  # fmt: skip


def press_case(task: str, contact_set: str, mover: str, fixture: str | int, u, half):
    """(model, data, mover geoms, u, face): the robot limp and weightless at its keyframe, a
    plate of half size `half` (a fixture of the scene, moved) `GAP` beyond the extreme point
    along `u` of the mover's colliders (`mover`: a geom, or a name prefix ending in "_" for all
    colliders so named), `FORCE` along `u` on the body of the first. `face` = the plate's near
    face . u."""
    env = _env(task, contact_set)
    m = _limp_weightless(env.mj_model)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    if mover.endswith("_"):
        geoms = [g for g in range(m.ngeom) if m.geom(g).name.startswith(mover)
                 and (m.geom_contype[g] or m.geom_conaffinity[g])]  # fmt: skip
    else:
        geoms = [_geom(m, mover)]
    f = fixture if isinstance(fixture, int) else _geom(m, fixture)
    u = np.asarray(u, float)
    tip = _tip(m, d.geom_xpos, d.geom_xmat, geoms, u)
    tip_geom = max(geoms, key=lambda g: _tip(m, d.geom_xpos, d.geom_xmat, [g], u))
    thick = float(np.abs(u) @ half)
    centre = d.geom_xpos[tip_geom] + u * (tip - d.geom_xpos[tip_geom] @ u + GAP + thick)
    _place_plate(m, d, f, centre, half)
    d.xfrc_applied[m.geom_bodyid[geoms[0]], :3] = FORCE * u
    mujoco.mj_forward(m, d)
    return m, d, geoms, u, tip + GAP


def simulate(m, d, backend: str) -> tuple[np.ndarray, np.ndarray]:
    """(geom_xpos, geom_xmat) after `STEPS` physics steps from `d`, in MuJoCo C ("c") or MJX
    (one jitted `lax.scan`)."""
    if backend == "c":
        for _ in range(STEPS):
            mujoco.mj_step(m, d)
        return d.geom_xpos, d.geom_xmat
    mx = mjx.put_model(m)
    run = jax.jit(lambda s: jax.lax.scan(lambda c, _: (mjx.step(mx, c), None), s, None,
                                         length=STEPS)[0])  # fmt: skip
    out = jax.device_get(run(mjx.put_data(m, d)))
    return np.asarray(out.geom_xpos), np.asarray(out.geom_xmat)


def depth(m, d, geoms, u, face, backend: str = "c") -> float:
    """How far the mover's extreme point ends inside the plate after `STEPS`."""
    xpos, xmat = simulate(m, d, backend)
    return _tip(m, xpos, xmat, geoms, u) - face


def _cabinet_wall(m) -> int:
    """A static collider of the lateral cabinet (a fixture: contype has FIXTURE)."""
    return next(g for g in _colliders(m, "lateral_cabinet") if m.geom_contype[g] & scene.FIXTURE)


CASES = {  # name: (task, moving geom, fixture, direction, plate half size)
    "hand on table": ("push", "lh_", "table_top_collision", (0, 0, -1), (0.1, 0.1, 0.02)),
    "torso on cabinet": ("cabinet", "torso", _cabinet_wall, (1, 0, 0), (0.02, 0.08, 0.08)),
    # the shoulder housing stands 9 cm in front of the torso box: "links" touch fixtures in hb.
    # The plate spans the housing's length: the push pitches the torso about the contact.
    "shoulder housing on table": ("push", "shoulders", "table_top_collision", (1, 0, 0),
                                  (0.02, 0.2, 0.3)),
}


def _case(name: str, contact_set: str):
    task, mover, fixture, u, half = CASES[name]
    if callable(fixture):
        fixture = fixture(_env(task, contact_set).mj_model)
    return press_case(task, contact_set, mover, fixture, u, np.asarray(half, float))


@pytest.mark.timeout(300)
@pytest.mark.parametrize("name", sorted(CASES))
def test_robot_stops_on_fixtures_with_hb_contacts_only(name):
    held = depth(*_case(name, "hb"))
    through = depth(*_case(name, "reduced"))
    assert held < HELD, (name, held)
    assert through > THROUGH, (name, through)


def drop_case(contact_set: str):
    """bookshelf_simple with the robot 5 m away: book_a laid as book_flat lies, 3 cm over it.
    Returns (model, data, top collider, base collider)."""
    env = _env("h1hand-bookshelf_simple-v0", contact_set)
    m = copy.deepcopy(env.mj_model)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.qpos[0] = -5.0
    mujoco.mj_forward(m, d)
    (top,), (base,) = _colliders(m, "book_a"), _colliders(m, "book_flat")
    up = np.array([0.0, 0.0, 1.0])

    def extent(g):
        return support(m.geom_type[g], m.geom_size[g], np.zeros(3), d.geom_xmat[g].reshape(3, 3),
                       up)  # fmt: skip

    jnt = m.body_jntadr[m.geom_bodyid[top]]
    adr = m.jnt_qposadr[jnt]
    base_body = m.geom_bodyid[base]
    d.qpos[adr + 3 : adr + 7] = d.xquat[base_body]
    mujoco.mj_forward(m, d)
    lift = d.geom_xpos[base] @ up + extent(base) + extent(top) + 0.03
    offset = d.xpos[m.geom_bodyid[top]] - d.geom_xpos[top]  # the collider sits off its body
    d.qpos[adr : adr + 3] = np.array([*d.geom_xpos[base][:2], lift]) + offset
    mujoco.mj_forward(m, d)
    return m, d, top, base


def gap_after_drop(m, d, top, base, backend: str) -> float:
    """How far the dropped book's bottom ends above the base book's top (< 0: inside)."""
    up = np.array([0.0, 0.0, 1.0])
    xpos, xmat = simulate(m, d, backend)
    return -_tip(m, xpos, xmat, [top], -up) - _tip(m, xpos, xmat, [base], up)


@pytest.mark.timeout(300)
def test_book_rests_on_book_with_hb_contacts_only():
    assert abs(gap_after_drop(*drop_case("hb"), "c")) < HELD
    assert gap_after_drop(*drop_case("reduced"), "c") < -THROUGH


def test_hb_bits_on_push():
    """hb: the table touches the robot's colliders, link capsules and hands; the box touches
    the robot, its link capsules and other objects. reduced: the bits earlier versions used,
    the link capsules touching nothing."""
    for contact_set, table, box_type, box_aff, links in (
        ("hb", scene.FIXTURE | scene.FLOOR | scene.HANDS | scene.LINKS,
         scene.HANDS | scene.OBJECT | scene.LINKS,
         scene.FLOOR | scene.FIXTURE | scene.OBJECT | 2, scene.LINKS),
        ("reduced", scene.FIXTURE, scene.HANDS, scene.FLOOR | scene.FIXTURE, 0),
    ):  # fmt: skip
        m = _env("push", contact_set).mj_model
        g = _geom(m, "table_top_collision")
        assert (m.geom_contype[g], m.geom_conaffinity[g]) == (table, 0), contact_set
        g = _geom(m, "object_collision")
        assert (m.geom_contype[g], m.geom_conaffinity[g]) == (box_type, box_aff), contact_set
        for name in ("shoulders", "left_shoulder_roll", "right_ankle", "left_hip_yaw"):
            g = _geom(m, name)
            assert (m.geom_contype[g], m.geom_conaffinity[g]) == (0, links), (contact_set, name)


def test_prism_keeps_the_cylinder_area_and_frame():
    """A colliding cylinder becomes a 16-gon prism: every vertex on the circumradius of equal
    area, at +-half length along the cylinder's axis, the geom where the cylinder was."""
    r16 = scene.prism_radius(0.2, 16)
    assert 16 / 2 * r16**2 * np.sin(2 * np.pi / 16) == pytest.approx(np.pi * 0.2**2)
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(pos=(0.3, 0.2, 0.5))
    body.add_freejoint()
    geom = body.add_geom(name="w", type=scene.CYLINDER, size=(0.2, 0.03, 0), pos=(0, 0.4, 0),
                         quat=scene.Y_AXIS, contype=1, conaffinity=1, density=0.0)  # fmt: skip
    body.add_geom(type=scene.SPHERE, size=(0.01, 0, 0), contype=0, conaffinity=0)
    scene.cylinder_to_prism(spec, geom, 16)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    g = _geom(m, "w")
    mesh = m.geom_dataid[g]
    verts = m.mesh_vert[m.mesh_vertadr[mesh] : m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
    world = d.geom_xpos[g] + verts @ d.geom_xmat[g].reshape(3, 3).T
    rel = world - np.array([0.3, 0.6, 0.5])
    along = rel[:, 1]
    np.testing.assert_allclose(np.sort(np.unique(along.round(6))), [-0.03, 0.03], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(rel[:, [0, 2]], axis=1), r16, rtol=1e-6)


def test_every_manipulation_task_has_no_colliding_cylinder_in_hb():
    """MJX has no box-cylinder pair: `use_hb_contacts` leaves no colliding cylinder."""
    for task in ("powerlift", "basketball"):
        m = _env(task, "hb").mj_model
        live = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        assert not (live & (m.geom_type == scene.CYLINDER)).any(), task
        assert (live & (m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)).sum() >= 1, task


def test_task_sets_its_prism_sides():
    """`ManipulationTask.prism_sides` reaches the prisms: 2 x sides vertices each."""
    for sides in (scene.PRISM_SIDES, 12):
        task = copy.copy(load("powerlift")[1].task)
        task.prism_sides = sides
        m = HumanoidEnv(task, "h1hand").mj_model
        prisms = scene.prism_meshes(m)
        assert len(prisms) == 2 and all(m.mesh_vertnum[i] == 2 * sides for i in prisms), sides


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("name", sorted(CASES))
def test_mjx_agrees_with_c_on_the_pressed_robot(name):
    c = depth(*_case(name, "hb"))
    j = depth(*_case(name, "hb"), backend="mjx")
    assert j < HELD and abs(j - c) < MJX_TOL, (name, c, j)


# Failed while bookshelf's whole side and back panels (0.96-0.99 m bounding spheres) outranked
# the book-book pair (78th of 720) in MJX's cull of 12: segmented panels and a cap of 32 keep it.
@pytest.mark.slow  # 28 s idle: make test keeps the cull's other checks (test_pair_cap.py)
@pytest.mark.timeout(600)
def test_mjx_agrees_with_c_on_the_dropped_book():
    c = gap_after_drop(*drop_case("hb"), "c")
    j = gap_after_drop(*drop_case("hb"), "mjx")
    assert abs(j) < HELD and abs(j - c) < MJX_TOL, (c, j)


def package_heights(m, backend: str) -> np.ndarray:
    """Truck's packages' body z after `STEPS` from the keyframe (the robot 5 m away)."""
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.qpos[0] = -5.0
    mujoco.mj_forward(m, d)
    bodies = [b for b in range(m.nbody) if m.body(b).name.startswith("package_")]
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in bodies and m.geom_contype[g]]
    xpos, _ = simulate(m, d, backend)
    return np.array([xpos[g][2] for g in geoms])


# Failed at truck's earlier cap of 12: the stacked packages' box-box pairs ranked past it in
# MJX's cull in every state (pair_cap) and the upper packages sank into the lower ones.
@pytest.mark.slow  # 26 s cold
@pytest.mark.timeout(600)
def test_mjx_keeps_truck_packages_stacked():
    m = _env("truck", "hb").mj_model
    c, j = package_heights(m, "c"), package_heights(m, "mjx")
    assert len(c) == 5 and np.abs(j - c).max() < MJX_TOL, (c, j)


def test_contact_set_is_checked_and_old_runs_resume_as_reduced(tmp_path):
    with pytest.raises(ValueError, match=r"contact_set.*'full'.*'hb', 'reduced'"):
        load("push", contact_set="full")
    with pytest.raises(ValueError, match=r"train.contact_set"):
        TrainConfig(contact_set="HB")
    saved = dataclasses.asdict(Config())
    assert saved["train"]["contact_set"] == "hb"
    del saved["train"]["contact_set"]  # a config.json written before the switch existed
    (tmp_path / "config.json").write_text(json.dumps(saved))
    assert runlog.load_config(tmp_path).train.contact_set == "reduced"
