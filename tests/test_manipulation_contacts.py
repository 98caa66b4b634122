"""HumanoidBench's manipulation scenes in contact: CPU MuJoCo on the very model MJX compiles
(contact bits and geometry are model data): what rests on what, what the hands move."""

from __future__ import annotations

import math
import types

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from sirl_jax.envs import make
from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation import base as manip
from sirl_jax.envs.tasks.manipulation.highbar import HighBarTask


def close(a, b, tol=1e-5):
    np.testing.assert_allclose(np.asarray(a), b, rtol=tol, atol=tol)


def _site(env, name):
    return env.robot.site_ids[name]

# -- contacts (CPU MuJoCo on the compiled model) ---------------------------------------------
def _settle(model, data, steps):
    for _ in range(steps):
        mujoco.mj_step(model, data)


def _pairs(model, data):
    return {frozenset((model.geom(c.geom1).name, model.geom(c.geom2).name))
            for c in data.contact[: data.ncon]}  # fmt: skip


@pytest.mark.timeout(120)
def test_profile_keeps_only_hand_object_and_world_pairs():
    """The "reduced" contact set (the "hb" bits: tests/test_contact_sets.py), hands off the
    floor (`hand_floor` "none"; with the default "all" they touch the floor too)."""
    env = make("push", contact_set="reduced", hand_floor="none")
    m = env.mj_model
    hands = set(env.robot.geom_groups["hands"])
    box = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "object_collision")
    floor_bit = make("push", contact_set="reduced").mj_model.geom_conaffinity
    for g in range(m.ngeom):
        name = m.geom(g).name
        if name in hands:  # hands touch the box only: not the floor, table or the robot
            assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == scene.HANDS, name
            assert floor_bit[g] == scene.HANDS | scene.FLOOR, name
    for g in range(m.ngeom):
        if m.geom(g).name.startswith("table"):
            assert m.geom_contype[g] == scene.FIXTURE and m.geom_conaffinity[g] == 0
    assert m.geom_contype[box] & scene.HANDS and m.geom_conaffinity[box] & scene.FIXTURE


@pytest.mark.timeout(120)
def test_push_box_rests_on_table_and_hand_moves_it():
    """The "reduced" set, where only the hands touch the box: with their colliders off the box
    stays (with "hb" the forearm beside the palm touches it as well)."""
    env = make("push", contact_set="reduced")
    m = env.mj_model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    box_adr, _ = manip.free_joint_adr(m, "free_object")
    m.opt.gravity[:] = 0  # the robot floats; only the box is tested
    d.qpos[box_adr + 2] = 1.1  # dropped from 0.1 m above the table
    m.opt.gravity[:] = (0, 0, -9.81)
    robot_dofs = slice(0, env.robot.nv_robot)
    for _ in range(400):  # hold the robot still, let the box fall onto the table
        d.qvel[robot_dofs] = 0
        d.qpos[: env.robot.nq_robot] = m.key_qpos[0][: env.robot.nq_robot]
        mujoco.mj_step(m, d)
    close(d.qpos[box_adr + 2], 1.0, tol=2e-3)  # top of the table 0.9 + half size 0.1
    assert frozenset(("table_top_collision", "object_collision")) in _pairs(m, d)
    # the left palm pushed 2 cm into the box's -y face pushes it away (+y); with the hands'
    # colliders off (locomotion profile) nothing touches it
    mujoco.mj_forward(m, d)
    palm = d.geom("lh_palm1").xpos.copy()
    start = palm + np.array([0.0, 0.09, 0.0])
    for contacts, moved in ((True, True), (False, False)):
        if not contacts:
            for g in env.robot.geom_ids["hands"]:
                m.geom_conaffinity[g] = 0
        d.qpos[box_adr : box_adr + 3] = start
        d.qpos[box_adr + 3 : box_adr + 7] = (1, 0, 0, 0)
        d.qvel[:] = 0
        m.opt.gravity[:] = 0
        for _ in range(50):
            d.qvel[robot_dofs] = 0
            d.qpos[: env.robot.nq_robot] = m.key_qpos[0][: env.robot.nq_robot]
            mujoco.mj_step(m, d)
        shift = np.linalg.norm(d.qpos[box_adr : box_adr + 3] - start)
        assert (shift > 0.01) == moved, (contacts, shift)


@pytest.mark.timeout(120)
def test_dumbbell_rests_on_floor_and_cubes_on_palms():
    env = make("powerlift")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    _settle(m, d, 200)
    adr, _ = manip.free_joint_adr(m, "free_dumbbell")
    # weights r 0.2 on the floor, as 12-gon prisms of the same area ("hb" contact set): the
    # prism's lowest point lies between its edge midpoint and its vertex radius
    assert env.task.prism_sides == 12
    r_prism = scene.prism_radius(0.2, 12)
    assert r_prism * math.cos(math.pi / 12) - 1e-3 < d.qpos[adr + 2] < r_prism + 1e-3
    assert {"weight_0_collision", "weight_1_collision"} <= set().union(*_pairs(m, d))
    close(m.body_subtreemass[manip.body_id(m, "dumbbell")], 104.0, tol=0.05)
    env = make("cube")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.ctrl[:] = env.robot.action_to_ctrl(env.robot.keyframe_action)
    _settle(m, d, 100)
    touched = {name for pair in _pairs(m, d) for name in pair}
    assert any(n.startswith("lh_") for n in touched) and any(n.startswith("rh_") for n in touched)
    for name in ("left_cube_to_rotate", "right_cube_to_rotate"):
        assert d.body(name).xpos[2] > 1.0  # held by the palms, not fallen through
        close(m.body_subtreemass[manip.body_id(m, name)], 0.0625)


def _held(env, model, data, steps):
    """Steps CPU MuJoCo with the robot pinned at its keyframe pose (only the objects move)."""
    nq, nv = env.robot.nq_robot, env.robot.nv_robot
    for _ in range(steps):
        data.qpos[:nq], data.qvel[:nv] = model.key_qpos[0][:nq], 0.0
        mujoco.mj_step(model, data)


def _free_pos(model, data, joint):
    adr, _ = manip.free_joint_adr(model, joint)
    return data.qpos[adr : adr + 3].copy()


@pytest.mark.timeout(120)
def test_insert_objects_rest_on_table_and_on_each_other():
    for name, rim in (("insert_normal", 0.07), ("insert_small", 0.03)):
        env = make(f"h1hand-{name}-v0")
        m, d = env.mj_model, mujoco.MjData(env.mj_model)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        _held(env, m, d, 300)
        for joint in ("free_peg_a", "free_peg_b", "free_block_a"):
            close(_free_pos(m, d, joint)[2], 0.95, tol=2e-3)  # the table top is at 0.95
        # the block dropped across peg a's rim (walls 1 cm up from the base, top at `rim`)
        adr, _ = manip.free_joint_adr(m, "free_block_a")
        peg_a = _free_pos(m, d, "free_peg_a")
        d.qpos[adr : adr + 3] = peg_a + np.array([0.0, 0.0, rim + 0.02])
        d.qpos[adr + 3 : adr + 7] = (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))  # along x
        d.qvel[:] = 0
        _held(env, m, d, 300)
        assert _free_pos(m, d, "free_block_a")[2] > peg_a[2] + rim - 2e-3, name


@pytest.mark.timeout(120)
def test_spoon_rests_on_table_and_in_cup():
    env = make("spoon")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    _held(env, m, d, 300)
    close(_free_pos(m, d, "free_spoon")[2], 0.9 + 0.007 - 0.0035, tol=1e-3)  # handle r 0.007
    # dropped into the cup: rests on its bottom (top at 0.9 + 0.03), inside the walls
    adr, _ = manip.free_joint_adr(m, "free_spoon")
    d.qpos[adr : adr + 3] = (0.75 - 0.05, -0.1, 1.0)
    d.qvel[:] = 0
    _held(env, m, d, 400)
    plate = d.geom("spoon_plate").xpos
    assert abs(plate[0] - 0.75) < 0.1 and abs(plate[1] + 0.1) < 0.1, plate
    assert 0.925 < plate[2] < 0.97, plate


@pytest.mark.timeout(120)
def test_window_tool_rests_on_hands_and_touches_pane():
    env = make("window")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    _held(env, m, d, 300)  # HumanoidBench's tool pose lies on the fingers of the stand pose
    assert _free_pos(m, d, "free_window_wiping_tool")[2] > 1.05
    touched = {n for pair in _pairs(m, d) for n in pair}
    assert any(n.startswith("lh_") for n in touched) and any(n.startswith("rh_") for n in touched)
    # the tool turned so the wiper faces +x, pushed into the pane (x 0.95): C finds the pair,
    # and the task's overlap query agrees, on the state and with the tool moved back
    adr, _ = manip.free_joint_adr(m, "free_window_wiping_tool")
    wipe, pane = m.geom("window_wipe_collision").id, m.geom("window_pane_collision").id
    for x, touching in ((0.435, True), (0.38, False)):
        d.qpos[adr : adr + 7] = (x, 0.0, 1.2, math.sqrt(0.5), 0.0, 0.0, -math.sqrt(0.5))
        d.qpos[adr + 7 : adr + 11] = (1, 0, 0, 0)
        mujoco.mj_forward(m, d)
        pairs = {frozenset((c.geom1, c.geom2)) for c in d.contact[: d.ncon]}
        assert (frozenset((wipe, pane)) in pairs) == touching, x
        kin = types.SimpleNamespace(geom_xpos=jnp.asarray(d.geom_xpos),
                                    geom_xmat=jnp.asarray(d.geom_xmat))  # fmt: skip
        query = env.task._touch.any(kin)
        assert bool(query) == touching, x


@pytest.mark.timeout(120)
def test_highbar_strong_hands_hold_the_bar():
    """h1strong: every hand actuator but WRJ2 at kp 50, +-50 N m. Holding the keyframe, the
    strong hands keep the robot on the bar for 1 s; h1hand's hands let it fall."""
    env = make("h1strong-highbar_hard-v0")
    m = env.mj_model
    for i, name in enumerate(env.robot.actuator_names):
        if name[:5] in ("lh_A_", "rh_A_"):
            kp, force = (10.0, 10.0) if name.endswith("WRJ2") else (50.0, 50.0)
            close(m.actuator_gainprm[i, 0], kp)
            close(m.actuator_forcerange[i], [-force, force])
    weak = HumanoidEnv(HighBarTask(), "h1hand")
    for e, holds in ((env, True), (weak, False)):
        m, d = e.mj_model, mujoco.MjData(e.mj_model)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        d.ctrl[:] = e.robot.action_to_ctrl(e.robot.keyframe_action)
        _settle(m, d, 500)
        assert (d.site("head").xpos[2] > 2.2) == holds, d.site("head").xpos


@pytest.mark.timeout(120)
def test_hands_open_the_door():
    """The robot, turned to face -x beyond the door with its arms raised forward, is moved
    toward -x (kinematically, 0.2 m/s), with its arm colliders off: its hands push the door's
    far face and the door swings open toward the corridor; with the hand colliders off as well
    it stays shut."""
    env = make("door")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    nq, nv = env.robot.nq_robot, env.robot.nv_robot
    door = m.joint("door_hinge").qposadr[0]
    m.geom_conaffinity[env.robot.geom_ids["arms"]] = 0
    for hands_on in (True, False):
        if not hands_on:
            m.geom_conaffinity[env.robot.geom_ids["hands"]] = 0
        mujoco.mj_resetDataKeyframe(m, d, 0)
        pose = m.key_qpos[0][:nq].copy()
        pose[0:7] = (1.5, 0.25, 0.98, 0, 0, 0, 1)  # yaw pi
        for side in ("left", "right"):
            pose[m.joint(f"{side}_shoulder_pitch").qposadr[0]] = -1.57
        for k in range(1200):  # the palms reach the door at root x ~1.2, the torso never does
            pose[0] = 1.5 - 0.0004 * k
            d.qpos[:nq], d.qvel[:nv] = pose, 0.0
            d.qvel[0] = -0.2
            mujoco.mj_step(m, d)
        assert (d.qpos[door] > 0.3) == hands_on, d.qpos[door]
        assert d.qpos[door] >= -1e-3  # never through the hinge limit


@pytest.mark.timeout(120)
def test_hand_pulls_the_drawer_open():
    """The left palm put between the drawer's handle bar and its front, then moved toward the
    robot (kinematically, 0.2 m/s for 1 s): it hooks the bar and the drawer slides out; with
    the hand colliders off it stays shut. The cubes rest on their shelves meanwhile."""
    env = make("cabinet")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    nq, nv = env.robot.nq_robot, env.robot.nv_robot
    drawer = m.joint("drawer_slide").qposadr[0]
    for hands_on in (True, False):
        if not hands_on:
            m.geom_conaffinity[env.robot.geom_ids["hands"]] = 0
        mujoco.mj_resetDataKeyframe(m, d, 0)
        mujoco.mj_forward(m, d)
        pose = m.key_qpos[0][:nq].copy()
        pose[:3] += np.array([0.565, 0.0, 0.74]) - d.geom("lh_palm1").xpos  # bar at x 0.51
        for _ in range(500):
            pose[0] -= 0.0004
            d.qpos[:nq], d.qvel[:nv] = pose, 0.0
            d.qvel[0] = -0.2
            mujoco.mj_step(m, d)
        assert (d.qpos[drawer] > 0.15) == hands_on, d.qpos[drawer]
        for name, z in (("lateral_cabinet_cube", 0.87), ("pullup_drawer_cube", 1.45)):
            close(d.body(name).xpos[2], z, tol=2e-3)


@pytest.mark.timeout(120)
def test_truck_carries_the_robot_and_the_packages():
    """The robot stands on the truck's bed (z 1.0) and on its ramp; the stacked packages stay
    put; a package dropped over the table lands on it, one dropped beside the truck on the
    floor."""
    env = make("truck")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    start = {n: d.body(n).xpos.copy() for n in ("package_a", "package_d", "package_e")}
    _held(env, m, d, 300)
    for name, pos in start.items():
        close(d.body(name).xpos, pos, tol=5e-3)
    for x, floor_z in ((6.0, 1.0), (3.3, 0.5)):  # on the bed; on the ramp's middle (z ~0.5)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        d.qpos[0], d.qpos[2] = x, 0.98 + floor_z + 0.05
        d.ctrl[:] = env.robot.action_to_ctrl(env.robot.keyframe_action)
        _settle(m, d, 100)  # 0.2 s: it lands on the surface instead of falling through
        assert d.qpos[2] > floor_z + 0.8, (x, d.qpos[2])
    for xy, rest_z in (((2.0, -1.7), 0.95 + 0.2), ((3.0, 2.0), 0.2)):
        mujoco.mj_resetDataKeyframe(m, d, 0)
        adr, _ = manip.free_joint_adr(m, "free_package_e")  # a 0.4 m cube
        d.qpos[adr : adr + 3] = (*xy, rest_z + 0.1)
        _held(env, m, d, 300)
        close(d.body("package_e").xpos[2], rest_z, tol=5e-3)


@pytest.mark.timeout(120)
def test_room_and_bookshelf_objects_rest():
    """Room's six objects at a reset pose stand on the floor (the headphone tips onto its
    side); the twelve bookshelf objects stay
    on their boards (the headphone settles 4 cm: its ear-cup boxes are narrower than the
    cylinders they replace). Room's objects in fixed mode: their `<body>` orientations."""
    env = make("room", hb_compat="fixed")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    qpos, _ = env.task.init(jax.random.PRNGKey(0), jnp.asarray(m.key_qpos[0]))
    d.qpos[:] = np.asarray(qpos)
    start = d.qpos[76:].reshape(6, 7)[:, :3].copy()
    _held(env, m, d, 300)
    moved = np.abs(d.qpos[76:].reshape(6, 7)[:, :3] - start).max(axis=1)
    assert (moved[[0, 1, 3, 4, 5]] < 0.02).all(), moved
    assert moved[2] < 0.1, moved  # the headphone starts tilted (HumanoidBench's quaternion)
    assert (np.abs(start[:, 1]) >= 1.2).all() and (np.diff(start[:, 0]) > 0).all()
    env = make("bookshelf_simple")
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    start = d.qpos[76:].reshape(12, 7)[:, :3].copy()
    _held(env, m, d, 300)
    moved = np.abs(d.qpos[76:].reshape(12, 7)[:, :3] - start).max(axis=1)
    assert (moved < 0.045).all(), moved
