"""HumanoidBench's manipulation tasks: registry, shapes, rewards by hand, contacts, rollouts.

Cheap checks run in CI: the registry and sizes, `jax.eval_shape` tracing of reset and reward
for every task, the reward numerics, and contact checks with CPU MuJoCo on the very model MJX
compiles (contact bits and geometry are model data). Compiled MJX rollouts (about a minute each
on 2 cores): push and cube in CI, the others marked slow.

Rollouts follow tests/test_tasks.py: E = 4 envs, `reset` then EPISODE + EXTRA steps in a
`lax.scan`, run weightless holding the keyframe pose (nothing falls, so every episode ends by
truncation at exactly EPISODE) and limp (no actuator force, normal gravity).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from rollouts import hold_and_limp

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs import TASKS, make
from sirl_jax.envs.tasks import manip
from sirl_jax.envs.tasks.basketball import CATCH, THROW, basketball_reward, throw_state
from sirl_jax.envs.tasks.cube import cube_reward, cube_terminated
from sirl_jax.envs.tasks.package import package_reward
from sirl_jax.envs.tasks.powerlift import powerlift_reward
from sirl_jax.envs.tasks.push import push_reward

E = 4
EPISODE = 60
EXTRA = 10
INF = math.inf
# HumanoidBench (spec §1): (episode length, success bar, obs dim, nq, nv)
HB = {
    "push": (500, 700, 163, 83, 81),
    "cube": (500, 370, 181, 90, 87),
    "powerlift": (1000, 800, 164, 83, 81),
    "basketball": (500, 1200, 164, 83, 81),
    "package": (1000, 1500, 173, 83, 81),
}
NAMES = [row.name for row in tasks.MANIPULATION]
CI_IDS = ("h1hand-push-v0", "h1hand-cube-v0")
ROOT_Z_TERMINATION = {"powerlift": 0.2}
ONLY_SUCCESS_ENDS = ("push", "package")


def _param(task_id: str):
    marks = () if task_id in CI_IDS else (pytest.mark.slow,)
    return pytest.param(task_id, marks=marks, id=task_id)


ALL_IDS = [_param(f"h1hand-{n}-v0") for n in NAMES]


def close(a, b, tol=1e-5):
    np.testing.assert_allclose(np.asarray(a), b, rtol=tol, atol=tol)


def _site(env, name):
    return env.robot.site_ids[name]


# -- registry, sizes, tracing (no compile) ------------------------------------------------------
def test_registry_rows():
    assert set(NAMES) == set(HB)
    for name, (length, bar, *_) in HB.items():
        spec = TASKS[f"h1hand-{name}-v0"]
        assert spec.episode_length == length and spec.success_bar == bar
        assert TASKS[name].id == spec.id
        assert f"h1-{name}-v0" not in TASKS


@pytest.mark.timeout(300)
def test_sizes_and_tracing_of_every_task():
    """Sizes as HumanoidBench's `gym.make`; reset and the reward traced (jax.eval_shape)."""
    for name in NAMES:
        length, bar, obs, nq, nv = HB[name]
        env = make(f"h1hand-{name}-v0")
        assert (env.mj_model.nq, env.mj_model.nv) == (nq, nv), name
        assert env.observation_size == obs and env.action_size == 61, name
        assert env.episode_length == length and env.success_bar == bar, name
        state = jax.eval_shape(env.reset, jax.random.PRNGKey(0))
        assert state.obs.shape == (obs,), name
        assert set(state.metrics) == set(env.metric_names()), name
        reward, terminated, task, metrics = jax.eval_shape(
            lambda d, t, env=env: env.task.evaluate(env.robot, d, t), state.physics, state.task
        )
        assert reward.shape == () and terminated.dtype == bool, name
        assert set(metrics) == set(env.metric_names()), name
        assert jax.tree.structure(task) == jax.tree.structure(state.task), name


# -- rewards against hand-worked values ------------------------------------------------------
def test_push_reward_at_and_away_from_goal():
    goal = jnp.array([0.8, 0.1, 1.0])
    # away: box 0.3 m from the goal (3-4-5 in xy: 0.18, 0.24), hand 0.5 m from the box
    box = jnp.array([0.8 - 0.18, 0.1 - 0.24, 1.0])
    hand = box + jnp.array([0.0, 0.3, 0.4])
    r, success, terms = push_reward(hand, box, goal)
    close(r, -0.1 * 0.5 - 0.3)
    assert not bool(success) and float(terms["reward_success"]) == 0.0
    # at the goal: 0.04 < 0.05 pays 1000 and terminates
    box = goal + jnp.array([0.04, 0.0, 0.0])
    r, success, terms = push_reward(box, box, goal)
    close(r, 1000.0 - 0.04)
    assert bool(success) and float(terms["success"]) == 1.0
    # just outside the 0.05 radius
    r, success, _ = push_reward(goal, goal + jnp.array([0.0, 0.06, 0.0]), goal)
    close(r, -0.006 - 0.06)
    assert not bool(success)


def test_package_reward():
    head, zz, force, _ = _standing_robot()
    dest = jnp.array([1.0, -1.0, 0.35])
    package = jnp.array([1.3, -1.4, 0.35])  # 0.5 from the destination
    hands = package + jnp.array([[0.0, 0.3, 0.4], [0.0, 0.0, -0.2]])  # 0.5 and 0.2
    r, success, terms = package_reward(head, zz, force, package, dest, hands)
    close(r, 1.0 - 1.5 - 0.07 + 0.35)
    assert not bool(success)
    # lifted above 1 m: height capped at 1; within 0.1 of the destination: + 1000, terminates
    package = dest + jnp.array([0.0, 0.0, 0.09])
    r, success, terms = package_reward(head, zz, force, package, dest, hands)
    close(terms["package_height"], 0.44)
    assert bool(success)
    hand_sum = float(jnp.sum(jnp.linalg.norm(hands - package, axis=-1)))
    close(r, 1.0 - 0.27 - 0.1 * hand_sum + 0.44 + 1000.0)
    package = jnp.array([1.0, -1.0, 1.6])
    _, success, terms = package_reward(head, zz, force, package, dest, hands)
    close(terms["package_height"], 1.0)
    assert not bool(success)
    # upright bound 0.8: zz 0.8 -> 1
    _, _, terms = package_reward(head, jnp.asarray(0.8), force, package, dest, hands)
    close(terms["stand_reward"], 1.0)


def _standing_robot():
    """head 1.7, zz 1, zero force and CoM velocity: stand terms 1, small_control 1."""
    return jnp.asarray(1.7), jnp.asarray(1.0), jnp.zeros(61), jnp.zeros(3)


def test_cube_orientation_matching():
    head, zz, force, v = _standing_robot()
    target = jnp.array([0.5, 0.5, 0.5, 0.5])
    cubes = jnp.array([[0.45, 0.21, 1.1], [0.45, -0.21, 1.1]])
    hands = cubes + jnp.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.6]])  # 0.05 (in), 0.6 (d = 1)
    # left cube matches; right differs by 0.15 in one entry (d = 0.5): mean (1 + 0.1**0.25) / 2
    quats = jnp.stack([target, target + jnp.array([0.15, 0.0, 0.0, 0.0])])
    r, terms = cube_reward(head, zz, force, v, quats, target, hands, cubes)
    orient = (1.0 + 0.1**0.25) / 2
    closeness = (1.0 + 0.1) / 2
    close(terms["orientation_alignment_reward"], orient)
    close(terms["cube_closeness_reward"], closeness)
    close(r, 0.2 + 0.5 * orient + 0.3 * closeness)
    # q and -q are the same rotation, but HumanoidBench's raw difference scores |2q| = 2: ~0
    r_neg, terms = cube_reward(head, zz, force, v, jnp.stack([-target, -target]), target, hands,
                               cubes)  # fmt: skip
    close(terms["orientation_alignment_reward"], 0.1 ** ((2 / 0.3) ** 2))
    assert float(r_neg) < float(r)


def test_cube_termination():
    assert not bool(cube_terminated(jnp.asarray(0.9), jnp.array([1.1, 0.61])))
    assert bool(cube_terminated(jnp.asarray(0.9), jnp.array([1.1, 0.59])))
    assert bool(cube_terminated(jnp.asarray(0.57), jnp.array([1.1, 1.1])))


@pytest.mark.parametrize(
    "z, expected",
    [(2.0, 1.0), (1.9, 1.0), (2.1, 1.0), (1.4, 0.1 ** (0.25**2)), (0.2, 0.1 ** (0.85**2)),
     (4.1, 0.1), (3.1, 0.1**0.25)],
)  # fmt: skip
def test_powerlift_height_tolerance(z, expected):
    head, zz, force, _ = _standing_robot()
    r, terms = powerlift_reward(head, zz, force, jnp.asarray(z))
    close(terms["reward_dumbbell_lifted"], expected)
    close(r, 0.2 + 0.8 * expected)


def test_powerlift_stand_terms():
    # head 1.1: d = (1.65 - 1.1) / 0.55 = 1 -> standing 0.1; zz 0.8 -> upright 1; zz -0.15 -> 0.5
    _, _, force, _ = _standing_robot()
    _, terms = powerlift_reward(jnp.asarray(1.1), jnp.asarray(0.8), force, jnp.asarray(2.0))
    close(terms["standing"], 0.1)
    close(terms["upright"], 1.0)
    _, terms = powerlift_reward(jnp.asarray(1.7), jnp.asarray(-0.15), force, jnp.asarray(2.0))
    close(terms["upright"], 0.5)


def test_basketball_stage_switch():
    head, zz, force, _ = _standing_robot()
    hoop = jnp.array([5.9, 0.0, 2.25])
    ball = jnp.array([0.3, 0.0, 1.5])
    # hands 0.2 (in bounds) and 0.6 (d = 0.4) from the ball: prox = max distance -> 0.1**0.16
    hands = ball + jnp.array([[0.0, 0.2, 0.0], [0.0, -0.6, 0.0]])
    prox = 0.1**0.16
    toward = 1.0 - math.hypot(5.6, 0.75) / 7.0 * 0.9  # linear, value 0.1 at the 7 m margin
    catch = jnp.asarray(CATCH, jnp.int32)
    r, stage, terms = basketball_reward(head, zz, force, hands, ball, hoop, jnp.asarray(False),
                                        catch)  # fmt: skip
    assert int(stage) == CATCH and float(terms["success_subtasks"]) == 0.0
    close(r, 0.5 + 0.5 * prox)
    # the first ball contact switches the stage in the same step, which pays the throw reward
    r, stage, terms = basketball_reward(head, zz, force, hands, ball, hoop, jnp.asarray(True),
                                        catch)  # fmt: skip
    assert int(stage) == THROW
    close(terms["reward_ball_success"], toward)
    close(r, 0.15 + 0.05 * prox + 0.8 * toward)
    # the stage never goes back
    r2, stage, _ = basketball_reward(head, zz, force, hands, ball, hoop, jnp.asarray(False), stage)
    assert int(stage) == THROW
    close(r2, r)
    # in the hoop: + 1000, toward = 1 - 0.03 / 7 * 0.9
    ball = hoop + jnp.array([0.0, 0.0, 0.03])
    r, _, terms = basketball_reward(head, zz, force, hands, ball, hoop, jnp.asarray(False), stage)
    assert float(terms["success"]) == 1.0
    hand_d = float(jnp.max(jnp.linalg.norm(hands - ball, axis=-1)))
    prox = float(_prox(hand_d))
    close(r, 1000.0 + 0.15 + 0.05 * prox + 0.8 * (1.0 - 0.03 / 7.0 * 0.9))


def _prox(d):
    """tol(d, (0, 0.2), margin 1), gaussian: 0.1 ** ((d - 0.2) ** 2) outside the bounds."""
    return 1.0 if d <= 0.2 else 0.1 ** ((d - 0.2) ** 2)


def test_basketball_throw_state():
    pos, vel = throw_state(jnp.asarray(0.0), jnp.asarray(1.0))
    close(pos, [1.5, 0.0, 1.3924])
    close(vel, [-7.5, 0.0, 0.0])
    pos, vel = throw_state(jnp.asarray(-math.pi / 2), jnp.asarray(1.0))
    close(pos, [0.0, -1.5, 1.3924])
    close(vel, [0.0, 7.5, 0.0])


def test_euler_to_quat():
    close(manip.euler_to_quat(jnp.zeros(3)), [1, 0, 0, 0])
    half = math.sqrt(0.5)
    close(manip.euler_to_quat(jnp.array([0.0, 0.0, math.pi / 2])), [half, 0, 0, half])
    close(manip.euler_to_quat(jnp.array([math.pi / 2, 0.0, 0.0])), [half, half, 0, 0])
    q = manip.euler_to_quat(jnp.array([0.3, -1.2, 2.5]))
    close(jnp.linalg.norm(q), 1.0)


# -- contacts (CPU MuJoCo on the compiled model) ---------------------------------------------
def _settle(model, data, steps):
    for _ in range(steps):
        mujoco.mj_step(model, data)


def _pairs(model, data):
    return {frozenset((model.geom(c.geom1).name, model.geom(c.geom2).name))
            for c in data.contact[: data.ncon]}  # fmt: skip


@pytest.mark.timeout(120)
def test_profile_keeps_only_hand_object_and_world_pairs():
    env = make("push")
    m = env.mj_model
    hands = set(env.robot.geom_groups["hands"])
    box = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "object_collision")
    for g in range(m.ngeom):
        name = m.geom(g).name
        if name in hands:  # hands touch the box only: not the floor, table or the robot
            assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == manip.HANDS, name
    for g in range(m.ngeom):
        if m.geom(g).name.startswith("table"):
            assert m.geom_contype[g] == manip.FIXTURE and m.geom_conaffinity[g] == 0
    assert m.geom_contype[box] & manip.HANDS and m.geom_conaffinity[box] & manip.FIXTURE


@pytest.mark.timeout(120)
def test_push_box_rests_on_table_and_hand_moves_it():
    env = make("push")
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
    close(d.qpos[adr + 2], 0.2, tol=2e-3)  # weights r 0.2 on the floor
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


# -- compiled rollouts ---------------------------------------------------------------------------
def _run(task_id):
    return hold_and_limp(task_id, E, EPISODE, EXTRA)


def _check_bookkeeping(trace):
    term, trunc = trace["terminated"], trace["truncated"]
    assert trace["finite"].all() and np.isfinite(trace["reward"]).all()
    assert not (term & trunc).any()
    assert (trace["last_length"][trunc] == EPISODE).all()
    for name, values in trace["metrics"].items():
        assert np.isfinite(values).all(), name


@pytest.mark.timeout(900)
@pytest.mark.parametrize("task_id", ALL_IDS)
def test_rollout(task_id):
    env, (start, _, hold), (_, _, limp) = _run(task_id)
    name = task_id.split("-")[1]
    assert start.obs.shape == (E, HB[name][2]) and np.isfinite(start.obs).all()
    _check_bookkeeping(hold)
    _check_bookkeeping(limp)
    assert not hold["terminated"].any()
    assert hold["truncated"][EPISODE - 1].all() and not hold["truncated"][: EPISODE - 1].any()
    if name in ONLY_SUCCESS_ENDS:  # the limp robot collapses; the object stays put
        assert not limp["terminated"].any() and limp["truncated"][EPISODE - 1].all()
    if name == "push":
        box = limp["final_obs"][: EPISODE - 1, :, -6:-3]
        assert (box[..., 2] > 0.97).all() and (box[..., 2] < 1.03).all()  # on the table
    if name not in ONLY_SUCCESS_ENDS:  # the collapse drops the objects / brings the root down
        assert limp["terminated"].any(axis=0).all()
    if name in ROOT_Z_TERMINATION:
        for trace in (hold, limp):
            fell = trace["final_obs"][..., 2] < ROOT_Z_TERMINATION[name]
            np.testing.assert_array_equal(trace["terminated"], fell)


@pytest.mark.timeout(900)
@pytest.mark.parametrize("task_id", [_param("h1hand-push-v0")])
def test_push_observation_and_goals(task_id):
    env, (start, _, _), _ = _run(task_id)
    goal = np.asarray(start.task)
    assert ((goal[:, 0] >= 0.7) & (goal[:, 0] <= 1.0)).all()
    assert ((goal[:, 1] >= -0.5) & (goal[:, 1] <= 0.5)).all() and (goal[:, 2] == 1.0).all()
    assert len({tuple(g) for g in goal.round(6)}) == E
    obs = np.asarray(start.obs)
    qpos = np.asarray(start.physics.qpos)
    close(obs[:, :76], qpos[:, :76])
    close(obs[:, 151:154], np.asarray(start.physics.site_xpos)[:, _site(env, "left_hand")])
    close(obs[:, 154:157], goal)
    close(obs[:, 157:160], qpos[:, 76:79])  # the box, after reset noise
    assert (np.abs(qpos[:, 76:79] - np.array([0.7, 0.0, 1.0])) <= 0.01 + 1e-6).all()


@pytest.mark.timeout(900)
@pytest.mark.parametrize("task_id", [_param("h1hand-cube-v0")])
def test_cube_reset_orientations(task_id):
    env, (start, _, _), _ = _run(task_id)
    qpos = np.asarray(start.physics.qpos)
    target = np.asarray(start.task)
    close(np.asarray(start.obs)[:, -4:], target)
    close(np.linalg.norm(target, axis=1), 1.0)
    close(qpos[:, :76], np.broadcast_to(env.mj_model.key_qpos[0][:76], (E, 76)))  # no noise
    for adr in (79, 86):
        close(np.linalg.norm(qpos[:, adr : adr + 4], axis=1), 1.0)
    assert len({tuple(q) for q in qpos[:, 79:83].round(5)}) == E
