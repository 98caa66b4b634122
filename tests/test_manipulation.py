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
import types

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from rollouts import hold_and_limp

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs import TASKS, make
from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.envs.tasks import manip
from sirl_jax.envs.tasks.basketball import CATCH, THROW, basketball_reward, throw_state
from sirl_jax.envs.tasks.bookshelf import BookshelfTask, bookshelf_reward
from sirl_jax.envs.tasks.cabinet import cabinet_reward
from sirl_jax.envs.tasks.cube import cube_reward, cube_terminated
from sirl_jax.envs.tasks.door import door_reward
from sirl_jax.envs.tasks.highbar import HighBarTask, highbar_reward
from sirl_jax.envs.tasks.insert import insert_reward, insert_terminated
from sirl_jax.envs.tasks.package import package_reward
from sirl_jax.envs.tasks.powerlift import powerlift_reward
from sirl_jax.envs.tasks.push import push_reward
from sirl_jax.envs.tasks.room import room_reward
from sirl_jax.envs.tasks.spoon import spoon_reward, spoon_target
from sirl_jax.envs.tasks.truck import ON_TABLE, ON_TRUCK, PICKED_UP, truck_reward
from sirl_jax.envs.tasks.window import window_reward

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
    "spoon": (1000, 650, 167, 83, 81),
    "window": (1000, 650, 171, 87, 84),
    "insert_normal": (500, 350, 190, 97, 93),
    "insert_small": (500, 350, 190, 97, 93),
    "highbar_hard": (1000, 750, 151, 76, 75),
    "door": (1000, 600, 155, 78, 77),
    "cabinet": (1000, 2500, 213, 109, 104),
    "room": (1000, 400, 229, 118, 111),
    "truck": (1000, 3000, 216, 111, 105),
    "bookshelf_simple": (1000, 2000, 308, 160, 147),
    "bookshelf_hard": (1000, 2000, 308, 160, 147),
    "kitchen": (500, 4, 97, 97, 95),
}
NAMES = [row.name for row in tasks.MANIPULATION]
IDS = {row.name: tasks.task_id(row.robot, row.name) for row in tasks.MANIPULATION}
CI_IDS = ("h1hand-push-v0", "h1hand-cube-v0")
ROOT_Z_TERMINATION = {"powerlift": 0.2, "spoon": 0.58, "insert_normal": 0.5}
ONLY_SUCCESS_ENDS = ("push", "package", "cabinet", "truck", "kitchen")


def _param(task_id: str):
    marks = () if task_id in CI_IDS else (pytest.mark.slow,)
    return pytest.param(task_id, marks=marks, id=task_id)


ALL_IDS = [_param(IDS[n]) for n in NAMES]


def close(a, b, tol=1e-5):
    np.testing.assert_allclose(np.asarray(a), b, rtol=tol, atol=tol)


def _site(env, name):
    return env.robot.site_ids[name]


# -- registry, sizes, tracing (no compile) ------------------------------------------------------
def test_registry_rows():
    assert set(NAMES) == set(HB)
    assert IDS["highbar_hard"] == "h1strong-highbar_hard-v0"
    for name, (length, bar, *_) in HB.items():
        spec = TASKS[IDS[name]]
        assert spec.episode_length == length and spec.success_bar == bar
        assert TASKS[name].id == spec.id
        assert f"h1-{name}-v0" not in TASKS


@pytest.mark.timeout(300)
def test_sizes_and_tracing_of_every_task():
    """Sizes as HumanoidBench's `gym.make`; reset and the reward traced (jax.eval_shape)."""
    for name in NAMES:
        length, bar, obs, nq, nv = HB[name]
        env = make(IDS[name])
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


def _lin(d, vam=0.1):
    """dm_control's linear sigmoid at d = distance / margin: max(1 - d (1 - vam), 0)."""
    return max(1.0 - d * (1.0 - vam), 0.0)


def test_insert_peg_tolerances():
    head, zz, force, _ = _standing_robot()
    pegs = jnp.array([[0.8, -0.2, 1.1], [0.8, 0.2, 1.1]])
    # solved: pegs at 1.1, block ends in them, the left hand on peg a
    hands = jnp.stack([pegs[0], pegs[1] + jnp.array([0.0, 0.0, 0.6])])
    r, terms = insert_reward(head, zz, force, pegs, pegs, hands)
    close(r, 1.0)
    # pegs 0.075 low (d = 0.5), one 0.075 high (the bound is a point): 0.55 each
    for dz in (-0.075, 0.075):
        _, terms = insert_reward(head, zz, force, pegs, pegs + jnp.array([0.0, 0.0, dz]), hands)
        close(terms["peg_height_reward"], _lin(0.5))
    # block ends 0.25 (d = 0.5) and 0.5 (d = 1) from the pegs; hands 0.45 and 0.7 from their
    # pegs: the nearer counts, d = (0.45 - 0.2) / 0.5 = 0.5 -> 0.1 ** 0.25
    ends = pegs + jnp.array([[0.0, 0.25, 0.0], [0.3, 0.4, 0.0]])
    hands = pegs + jnp.array([[0.0, 0.0, 0.45], [0.0, 0.0, 0.7]])
    r, terms = insert_reward(head, zz, force, ends, pegs, hands)
    target = (_lin(0.5) + _lin(1.0)) / 2
    close(terms["cube_target_reward"], target)
    close(terms["hand_tool_proximity_reward"], 0.1**0.25)
    close(r, (0.5 + 0.5 * target) * (0.5 + 0.5 * 0.1**0.25))
    # right hand pairs with peg b only: on peg a it is 0.4 from peg b
    hands = jnp.stack([pegs[0] + jnp.array([0.0, 0.0, 1.0]), pegs[0]])
    _, terms = insert_reward(head, zz, force, ends, pegs, hands)
    close(terms["hand_tool_proximity_reward"], 0.1 ** (0.4**2))
    assert not bool(insert_terminated(jnp.asarray(0.9), jnp.array([0.95, 0.95, 0.95, 0.51])))
    assert bool(insert_terminated(jnp.asarray(0.9), jnp.array([0.95, 0.49, 0.95, 0.95])))
    assert bool(insert_terminated(jnp.asarray(0.49), jnp.array([0.95, 0.95, 0.95, 0.95])))


def test_spoon_target_and_reward():
    centre = np.array([0.75, -0.1, 0.95])
    close(spoon_target(0), centre + [0.06, 0.0, 0.0])
    close(spoon_target(10), centre + [0.0, 0.06, 0.0])
    close(spoon_target(20), centre + [-0.06, 0.0, 0.0])
    close(spoon_target(40), spoon_target(0))
    head, zz, force, _ = _standing_robot()
    cup = jnp.array([0.75, -0.1, 0.9])
    target = spoon_target(5)
    handle = jnp.array([0.7, -0.1, 1.05])
    hands = jnp.stack([handle, handle + jnp.array([0.0, 0.0, 1.0])])
    # the plate on the target, inside the cup (z 0.05 above its base, 0.1 window around 0.1)
    r, terms = spoon_reward(head, zz, force, hands, handle, target, cup, target)
    close(terms["reward_spoon_in_cup"], 1.0)
    close(r, 1.0)
    # plate 0.12 above the target (d = 0.8), still in the cup (z offset 0.07 from cup z + 0.1)
    plate = target + jnp.array([0.0, 0.0, 0.12])
    r, terms = spoon_reward(head, zz, force, hands, handle, plate, cup, target)
    close(terms["spoon_spinning_reward"], 0.1**0.64)
    close(terms["reward_spoon_in_cup"], 1.0)
    close(r, 0.65 + 0.35 * 0.1**0.64)
    # 0.11 off the cup's centre in x: out of the cup
    plate = cup + jnp.array([0.11, 0.0, 0.1])
    _, terms = spoon_reward(head, zz, force, hands, handle, plate, cup, target)
    close(terms["reward_spoon_in_cup"], 0.0)


def test_window_reward_terms():
    head, zz, force, _ = _standing_robot()
    head0 = jnp.array([0.0, 0.0, 1.7])
    head_pos = head0 + jnp.array([0.4, 0.0, 0.0])  # moved 0.4: in bounds
    tool = jnp.array([0.6, 0.0, 1.2])
    hands = jnp.stack([tool, tool + jnp.array([0.0, 0.1, 0.0])])
    wipe_x = jnp.full(5, 0.92)
    args = (head, zz, force, head_pos, head0, jnp.asarray(-0.5), hands, tool)
    r, terms = window_reward(*args, wipe_x, jnp.asarray(True))
    close(r, 1.0)
    r, terms = window_reward(*args, wipe_x, jnp.asarray(False))
    close(r, 0.5)  # the wipe term needs the pane contact
    close(terms["window_contact_reward"], 1.0)
    # one site 0.2 short (d = 0.5): the min counts; the far hand (0.45) counts
    hands = jnp.stack([tool, tool + jnp.array([0.0, 0.45, 0.0])])
    r, terms = window_reward(head, zz, force, head_pos, head0, jnp.asarray(0.0), hands, tool,
                             wipe_x.at[3].set(0.72), jnp.asarray(True))  # fmt: skip
    close(terms["window_contact_reward"], _lin(0.5))
    close(terms["hand_tool_proximity_reward"], 0.1**0.25)
    close(terms["moving_wipe_reward"], 0.1)  # |v_z| 0 is the 0.5 margin below 0.5
    close(r, 0.5 * (0.2 + 0.4 * 0.1 + 0.4 * 0.1**0.25) + 0.5 * _lin(0.5))
    # the head moved 0.35 or 0.45: d = 0.5 -> 0.1 ** 0.25 on the stand term
    for dx in (0.35, 0.45):
        r, _ = window_reward(head, zz, force, head0 + jnp.array([dx, 0.0, 0.0]), head0,
                             jnp.asarray(0.5), hands, tool, wipe_x, jnp.asarray(True))
        close(r, 0.5 * (0.2 * 0.1**0.25 + 0.4 + 0.4 * 0.1**0.25) + 0.5)


@pytest.mark.parametrize(
    "zz, feet, upright, feet_term",
    [(-1.0, (4.8, 4.8), 1.0, 1.0), (1.0, (2.8, 2.8), 0.0, 0.5), (0.0, (3.8, 3.8), 1 - 0.9 / 1.9,
     0.75), (-0.9, (5.0, 3.0), 1.0, 0.8)],  # mean 4.0: d = 0.4
)  # fmt: skip
def test_highbar_reward(zz, feet, upright, feet_term):
    _, _, force, _ = _standing_robot()
    r, terms = highbar_reward(jnp.asarray(zz), jnp.asarray(feet), force)
    close(terms["upright_reward"], upright)
    close(terms["feet_reward"], feet_term)
    close(r, upright * feet_term)


def test_door_reward():
    head, zz, force, _ = _standing_robot()
    hatch = jnp.array([0.8, 0.4, 1.2])
    hands = jnp.stack([hatch, hatch + jnp.array([0.0, 0.0, 2.0])])
    # door at 0.5 rad: 0.25; hatch 0.75 (in bounds); hand on the hatch; imu at x 1.2
    r, terms = door_reward(head, zz, force, jnp.asarray(0.5), jnp.asarray(0.75), hatch, hands,
                           jnp.asarray(1.2))  # fmt: skip
    close(terms["door_openness_reward"], 0.25)
    close(r, 0.1 + 0.45 * 0.25 + 0.05 + 0.05 + 0.35)
    # door past 1 rad: capped at 1; hatch 0.375, nearest hand 0.75 (d = 0.5 each, linear with
    # 0.1 at the margin: 0.55); imu x 0.7 (d = 0.5, linear with 0 at the margin: 0.5)
    hands = jnp.stack([hatch + jnp.array([0.0, 0.0, 0.75]), hatch + jnp.array([0.0, 0.0, 2.0])])
    r, terms = door_reward(head, zz, force, jnp.asarray(1.2), jnp.asarray(0.375), hatch, hands,
                           jnp.asarray(0.7))  # fmt: skip
    close(terms["door_openness_reward"], 1.0)
    close(terms["hand_hatch_proximity_reward"], _lin(0.5))
    close(terms["passage_reward"], 0.5)
    close(r, 0.1 + 0.45 + 0.05 * _lin(0.5) * 2 + 0.35 * 0.5)
    # upright's margin is 0.9 in door: zz 0.45 -> 0.5
    _, terms = door_reward(head, jnp.asarray(0.45), force, jnp.asarray(0.0), jnp.asarray(0.0),
                           hatch, hands, jnp.asarray(0.0))  # fmt: skip
    close(terms["stand_reward"], 0.5)


def _cabinet(stage, q=(0.0,) * 5, drawer_cube=(0.9, 0.0, 0.58), lateral_cube=(0.9, 0.0, 0.87)):
    head, zz, force, _ = _standing_robot()
    return cabinet_reward(head, zz, force, jnp.asarray(stage, jnp.int32), jnp.asarray(q),
                          jnp.asarray(drawer_cube), jnp.asarray(lateral_cube))  # fmt: skip


def test_cabinet_subtasks_complete_at_their_thresholds():
    # q order: drawer, left door, right door, pulling door, pull-up door
    r, stage, _ = _cabinet(1, (0, 0, 0, -0.37, 0))  # 0.925 of the 0.4 m slide
    close(r, 0.2 + 0.8 * 0.925)
    assert int(stage) == 1
    r, stage, terms = _cabinet(1, (0, 0, 0, -0.39, 0))  # 0.975 > 0.95: + 100
    close(r, 0.2 + 0.8 * 0.975 + 100.0)
    assert int(stage) == 2 and float(terms["success_subtasks"]) == 1.0
    r, stage, _ = _cabinet(2, (0.42, 0, 0, -0.39, 0))  # 0.933 of 0.45
    close(r, 0.2 + 0.8 * 0.42 / 0.45)
    assert int(stage) == 2
    r, stage, _ = _cabinet(2, (0.43, 0, 0, 0, 0))
    close(r, 0.2 + 0.8 * 0.43 / 0.45 + 200.0)
    assert int(stage) == 3
    # subtask 3: the drawer cube inside the lateral cabinet, the left door half open
    r, stage, _ = _cabinet(3, (0.45, -0.5, 0, 0, 0), drawer_cube=(0.9, 0.0, 0.94))
    close(r, 0.2 + 0.8 * (0.5 * 1.0 + 0.5 * 0.5) + 300.0)
    assert int(stage) == 4
    # outside: x 0.45 and z 0.3 off (d = 0.5 each, linear 0.55), y centred; the right door
    # open past 1 rad counts 1 (the better door)
    r, stage, terms = _cabinet(3, (0, -0.5, 1.2, 0, 0), drawer_cube=(1.35, 0.0, 1.24))
    proximity = 0.3 * (_lin(0.5) + 1.0) / 2 + 0.7 * _lin(0.5)
    close(terms["drawer_cube_proximity_reward"], proximity)
    close(r, 0.2 + 0.8 * (0.5 * proximity + 0.5))
    assert int(stage) == 3
    # subtask 4: the lateral cube in the pull-up drawer: + 400, stage 5 (done)
    r, stage, terms = _cabinet(4, (0, 0, 0, 0, 1.2), lateral_cube=(0.9, 0.1, 1.54))
    close(r, 0.2 + 0.8 + 400.0)
    assert int(stage) == 5 and float(terms["success"]) == 1.0


def test_cabinet_bonus_is_paid_once():
    """The pulling door held open for 5 steps: 100 in the first, none after (the stage moved
    on to the drawer)."""
    stage, bonus = jnp.asarray(1, jnp.int32), []
    for _ in range(5):
        r, stage, _ = _cabinet(stage, (0, 0, 0, -0.4, 0))
        bonus.append(float(r) > 100.0)
    assert bonus == [True, False, False, False, False] and int(stage) == 2


def test_room_reward_spread():
    head, zz, force, _ = _standing_robot()
    together = jnp.tile(jnp.array([1.0, 2.0, 0.1]), (6, 1))
    r, terms = room_reward(head, zz, force, together)
    close(r, 1.0)
    # x alternating -1, 1: population variance 1 (y 0): d = 1/3 of the margin
    spread = together.at[:, 0].set(jnp.array([-1.0, 1.0] * 3)).at[:, 1].set(0.0)
    r, terms = room_reward(head, zz, force, spread)
    close(terms["room_object_organized"], 0.1 ** (1 / 9))
    close(r, 0.2 + 0.8 * 0.1 ** (1 / 9))
    # the larger of the two variances counts: y spread 2x as wide
    spread = spread.at[:, 1].set(jnp.array([-2.0, 2.0] * 3))
    _, terms = room_reward(head, zz, force, spread)
    close(terms["room_object_organized"], 0.1 ** ((4 / 3) ** 2))


def _truck(packages, status, z0, root=(100.0, 0.0, 1.0), table=(-100.0, 0.0, 0.45)):
    """truck_reward with the robot and the table body far from every package unless given (the
    "upon the table" test uses fixed bounds, not the body): the
    distance terms are then 0 and the reward is the events alone."""
    return truck_reward(jnp.asarray(1.0), jnp.asarray(root), jnp.asarray(table),
                        jnp.asarray(packages), jnp.asarray(status, jnp.int32), jnp.asarray(z0))


def test_truck_events_are_paid_once_each():
    start = np.array([[5.0, y, 1.1] for y in (-0.5, -0.25, 0.0, 0.25, 0.5)])
    z0 = start[:, 2].copy()
    status = np.full(5, ON_TRUCK)
    r, status, terms = _truck(start, status, z0)
    close(r, 0.0)
    lifted = start.copy()
    lifted[0, 2] += 0.11  # 0.11 above its first-step z: picked up
    r, status, terms = _truck(lifted, status, z0)
    close(r, 100.0)
    assert status.tolist() == [PICKED_UP] + [ON_TRUCK] * 4
    r, status, _ = _truck(lifted, status, z0)  # still held: nothing new
    close(r, 0.0)
    on_table = lifted.copy()
    on_table[0] = (2.0, -1.7, 0.95)
    r, status, terms = _truck(on_table, status, z0)
    close(r, 100.0)
    assert int(status[0]) == ON_TABLE and float(terms["packages_on_table"]) == 1.0
    r, status, _ = _truck(lifted, status, z0)  # taken off the table again: -100
    close(r, -100.0)
    assert int(status[0]) == PICKED_UP
    # from the truck straight over the table in one step (and 0.15 above its start): picked up
    # and placed, + 200
    both = on_table.copy()
    both[1] = (2.1, -1.6, 1.25)
    r, status, _ = _truck(both, status, z0)
    close(r, 300.0)  # package 0 placed again (+100), package 1 lifted and placed (+200)
    # all five placed: + 300 for the last three, + 1000, success
    done = np.array([[2.0 + 0.05 * k, -1.7, 1.25] for k in range(5)])
    r, status, terms = _truck(done, status, z0)
    close(r, 3 * 200.0 + 1000.0)
    assert (np.asarray(status) == ON_TABLE).all() and float(terms["success"]) == 1.0


def test_truck_distance_terms():
    start = np.array([[5.0, y, 1.1] for y in (-0.5, -0.25, 0.0, 0.25, 0.5)])
    status = np.array([PICKED_UP] + [ON_TRUCK] * 4)
    # the root 0.2 from the nearest truck package (in bounds), 2.2 from the picked one (d 0.5);
    # the picked one 4.2 from the table (d = 1: 0)
    root = start[1] + np.array([0.0, 0.0, 0.2])
    picked = root + np.array([0.0, 0.0, 2.2])
    packages = start.copy()
    packages[0] = picked
    table = picked + np.array([0.0, 4.2, 0.0])
    r, _, terms = _truck(packages, status, packages[:, 2] + 1.0, root=root, table=table)
    close(terms["reward_robot_package_truck"], 1.0)
    close(terms["reward_robot_package_picked_up"], 0.5)
    close(terms["reward_package_table"], 0.0)
    close(r, 1.5)
    _, _, terms = _truck(start, np.full(5, ON_TRUCK), start[:, 2], root=root)
    close(terms["reward_robot_package_picked_up"], 0.0)  # nothing picked up: 0


def test_bookshelf_reward_and_stages():
    head, zz, force, _ = _standing_robot()
    goal = jnp.array([0.8, 0.05, 0.95])
    obj = goal + jnp.array([0.1, 0.0, 0.0])  # within 0.15: placed
    hands = jnp.stack([obj, obj + 1.0])
    r, index, terms = bookshelf_reward(head, zz, force, obj, goal, hands, jnp.asarray(2))
    assert int(index) == 3 and float(terms["success_subtasks"]) == 3.0
    close(r, 0.2 + 0.4 + 0.4 + 300.0)  # the third placement pays 100 x 3
    obj = goal + jnp.array([0.0, 0.0, 0.65])  # d = (0.65 - 0.15) / 1 = 0.5 -> 0.55
    hands = jnp.stack([obj + jnp.array([1.0, 0.0, 0.0]), obj + jnp.array([0.0, 2.0, 0.0])])
    r, index, terms = bookshelf_reward(head, zz, force, obj, goal, hands, jnp.asarray(0))
    assert int(index) == 0
    close(terms["reward_proximity"], _lin(0.5))
    close(r, 0.2 + 0.4 * _lin(0.5) + 0.4 * math.exp(-1.0))


def test_bookshelf_orders():
    qpos = jnp.zeros(160)
    _, simple = BookshelfTask("bookshelf_simple").init(jax.random.PRNGKey(0), qpos)
    assert np.asarray(simple["order"]).tolist() == [5, 2, 9, 4, 1, 1]  # trophy, book_c, ...
    close(simple["goals"][0], [0.75, -0.25, 1.55])
    hard = BookshelfTask("bookshelf_hard")
    orders = set()
    for seed in range(8):
        _, state = hard.init(jax.random.PRNGKey(seed), qpos)
        order = np.asarray(state["order"])
        assert len(set(order[:5])) == 5 and order[5] == order[4] and order.max() < 12
        goals = {tuple(g) for g in np.asarray(state["goals"][:5]).round(4)}
        assert goals == {tuple(np.round(g, 4)) for g in np.asarray(simple["goals"][:5])}
        orders.add(tuple(order))
    assert len(orders) == 8


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
    cylinders they replace)."""
    env = make("room")
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
