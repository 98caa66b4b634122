"""HumanoidBench's staged manipulation rewards against hand-worked values (no jit): cabinet's
subtasks and one-off bonus, room's spread, truck's events and distances, bookshelf's stages and
orders, and the Euler-to-quaternion convention they use."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from hand_values import close, lin, standing_robot

from sirl_jax.envs.tasks.manipulation import base as manip
from sirl_jax.envs.tasks.manipulation.bookshelf import BookshelfTask, bookshelf_reward
from sirl_jax.envs.tasks.manipulation.cabinet import cabinet_reward
from sirl_jax.envs.tasks.manipulation.room import room_reward
from sirl_jax.envs.tasks.manipulation.truck import (
    ON_TABLE,
    ON_TRUCK,
    PICKED_UP,
    truck_lists,
    truck_reward,
)


def _cabinet(stage, q=(0.0,) * 5, drawer_cube=(0.9, 0.0, 0.58), lateral_cube=(0.9, 0.0, 0.87)):
    head, zz, force, _ = standing_robot()
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
    proximity = 0.3 * (lin(0.5) + 1.0) / 2 + 0.7 * lin(0.5)
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
    head, zz, force, _ = standing_robot()
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
    head, zz, force, _ = standing_robot()
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
    close(terms["reward_proximity"], lin(0.5))
    close(r, 0.2 + 0.4 * lin(0.5) + 0.4 * math.exp(-1.0))


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
