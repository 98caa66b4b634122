"""HumanoidBench's manipulation rewards and terminations against hand-worked values (no jit)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.envs.tasks.manipulation import base as manip
from sirl_jax.envs.tasks.manipulation.basketball import CATCH, THROW, basketball_reward, throw_state
from sirl_jax.envs.tasks.manipulation.bookshelf import BookshelfTask, bookshelf_reward
from sirl_jax.envs.tasks.manipulation.cabinet import cabinet_reward
from sirl_jax.envs.tasks.manipulation.cube import cube_reward, cube_terminated
from sirl_jax.envs.tasks.manipulation.door import door_reward
from sirl_jax.envs.tasks.manipulation.highbar import highbar_reward
from sirl_jax.envs.tasks.manipulation.insert import insert_reward, insert_terminated
from sirl_jax.envs.tasks.manipulation.package import package_reward
from sirl_jax.envs.tasks.manipulation.powerlift import powerlift_reward
from sirl_jax.envs.tasks.manipulation.push import push_reward
from sirl_jax.envs.tasks.manipulation.room import room_reward
from sirl_jax.envs.tasks.manipulation.spoon import spoon_reward, spoon_target
from sirl_jax.envs.tasks.manipulation.truck import (
    ON_TABLE,
    ON_TRUCK,
    PICKED_UP,
    truck_lists,
    truck_reward,
)
from sirl_jax.envs.tasks.manipulation.window import window_reward


def close(a, b, tol=1e-5):
    np.testing.assert_allclose(np.asarray(a), b, rtol=tol, atol=tol)


def _site(env, name):
    return env.robot.site_ids[name]

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


def _truck(packages, status, z0, root=(100.0, 0.0, 1.0), table=(-100.0, 0.0, 0.45), zz=-1.0):
    """truck_reward ("fixed" lists) with the robot and the table body far from every package
    unless given (the "upon the table" test uses fixed bounds, not the body), and the torso
    upside down unless given (upright 0): the reward is then the events alone."""
    lists = {**truck_lists(), "status": jnp.asarray(status, jnp.int32)}
    r, lists, terms = truck_reward(jnp.asarray(zz), jnp.asarray(root), jnp.asarray(table),
                                   jnp.asarray(packages), lists, jnp.asarray(z0))  # fmt: skip
    return r, lists["status"], terms


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
    r, _, terms = _truck(packages, status, packages[:, 2] + 1.0, root=root, table=table, zz=1.0)
    close(terms["reward_robot_package_truck"], 1.0)
    close(terms["reward_robot_package_picked_up"], 0.5)
    close(terms["reward_package_table"], 0.0)
    close(r, 1.0 + 1.5)  # upright * (1 + the three terms), HumanoidBench's constant 1 included
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
