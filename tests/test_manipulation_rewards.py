"""HumanoidBench's manipulation rewards and terminations against hand-worked values (no jit)."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest
from hand_values import close, gauss_prox, lin, standing_robot

from sirl_jax.envs.tasks.manipulation.basketball import CATCH, THROW, basketball_reward, throw_state
from sirl_jax.envs.tasks.manipulation.cube import cube_reward, cube_terminated
from sirl_jax.envs.tasks.manipulation.door import door_reward
from sirl_jax.envs.tasks.manipulation.highbar import highbar_reward
from sirl_jax.envs.tasks.manipulation.insert import insert_reward, insert_terminated
from sirl_jax.envs.tasks.manipulation.package import package_reward
from sirl_jax.envs.tasks.manipulation.powerlift import powerlift_reward
from sirl_jax.envs.tasks.manipulation.push import push_reward
from sirl_jax.envs.tasks.manipulation.spoon import spoon_reward, spoon_target
from sirl_jax.envs.tasks.manipulation.window import window_reward


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
    head, zz, force, _ = standing_robot()
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


def test_cube_orientation_matching():
    head, zz, force, v = standing_robot()
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
    head, zz, force, _ = standing_robot()
    r, terms = powerlift_reward(head, zz, force, jnp.asarray(z))
    close(terms["reward_dumbbell_lifted"], expected)
    close(r, 0.2 + 0.8 * expected)


def test_powerlift_stand_terms():
    # head 1.1: d = (1.65 - 1.1) / 0.55 = 1 -> standing 0.1; zz 0.8 -> upright 1; zz -0.15 -> 0.5
    _, _, force, _ = standing_robot()
    _, terms = powerlift_reward(jnp.asarray(1.1), jnp.asarray(0.8), force, jnp.asarray(2.0))
    close(terms["standing"], 0.1)
    close(terms["upright"], 1.0)
    _, terms = powerlift_reward(jnp.asarray(1.7), jnp.asarray(-0.15), force, jnp.asarray(2.0))
    close(terms["upright"], 0.5)


def test_basketball_stage_switch():
    head, zz, force, _ = standing_robot()
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
    prox = float(gauss_prox(hand_d))
    close(r, 1000.0 + 0.15 + 0.05 * prox + 0.8 * (1.0 - 0.03 / 7.0 * 0.9))


def test_basketball_throw_state():
    pos, vel = throw_state(jnp.asarray(0.0), jnp.asarray(1.0))
    close(pos, [1.5, 0.0, 1.3924])
    close(vel, [-7.5, 0.0, 0.0])
    pos, vel = throw_state(jnp.asarray(-math.pi / 2), jnp.asarray(1.0))
    close(pos, [0.0, -1.5, 1.3924])
    close(vel, [0.0, 7.5, 0.0])


def test_insert_peg_tolerances():
    head, zz, force, _ = standing_robot()
    pegs = jnp.array([[0.8, -0.2, 1.1], [0.8, 0.2, 1.1]])
    # solved: pegs at 1.1, block ends in them, the left hand on peg a
    hands = jnp.stack([pegs[0], pegs[1] + jnp.array([0.0, 0.0, 0.6])])
    r, terms = insert_reward(head, zz, force, pegs, pegs, hands)
    close(r, 1.0)
    # pegs 0.075 low (d = 0.5), one 0.075 high (the bound is a point): 0.55 each
    for dz in (-0.075, 0.075):
        _, terms = insert_reward(head, zz, force, pegs, pegs + jnp.array([0.0, 0.0, dz]), hands)
        close(terms["peg_height_reward"], lin(0.5))
    # block ends 0.25 (d = 0.5) and 0.5 (d = 1) from the pegs; hands 0.45 and 0.7 from their
    # pegs: the nearer counts, d = (0.45 - 0.2) / 0.5 = 0.5 -> 0.1 ** 0.25
    ends = pegs + jnp.array([[0.0, 0.25, 0.0], [0.3, 0.4, 0.0]])
    hands = pegs + jnp.array([[0.0, 0.0, 0.45], [0.0, 0.0, 0.7]])
    r, terms = insert_reward(head, zz, force, ends, pegs, hands)
    target = (lin(0.5) + lin(1.0)) / 2
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
    head, zz, force, _ = standing_robot()
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
    head, zz, force, _ = standing_robot()
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
    close(terms["window_contact_reward"], lin(0.5))
    close(terms["hand_tool_proximity_reward"], 0.1**0.25)
    close(terms["moving_wipe_reward"], 0.1)  # |v_z| 0 is the 0.5 margin below 0.5
    close(r, 0.5 * (0.2 + 0.4 * 0.1 + 0.4 * 0.1**0.25) + 0.5 * lin(0.5))
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
    _, _, force, _ = standing_robot()
    r, terms = highbar_reward(jnp.asarray(zz), jnp.asarray(feet), force)
    close(terms["upright_reward"], upright)
    close(terms["feet_reward"], feet_term)
    close(r, upright * feet_term)


def test_door_reward():
    head, zz, force, _ = standing_robot()
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
    close(terms["hand_hatch_proximity_reward"], lin(0.5))
    close(terms["passage_reward"], 0.5)
    close(r, 0.1 + 0.45 + 0.05 * lin(0.5) * 2 + 0.35 * 0.5)
    # upright's margin is 0.9 in door: zz 0.45 -> 0.5
    _, terms = door_reward(head, jnp.asarray(0.45), force, jnp.asarray(0.0), jnp.asarray(0.0),
                           hatch, hands, jnp.asarray(0.0))  # fmt: skip
    close(terms["stand_reward"], 0.5)
