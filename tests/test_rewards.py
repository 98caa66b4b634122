"""Reward numerics against values worked out by hand from HumanoidBench's formulas (spec §3).

Useful identities for the expectations: a gaussian tolerance with value_at_margin 0.1 at
normalised distance d equals 0.1 ** (d ** 2); linear with vam 0 equals 1 - d; quadratic with
vam 0 equals 1 - d ** 2 (all clipped at 0).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.envs import rewards as R
from sirl_jax.envs.tasks.locomotion.balance import balance_reward
from sirl_jax.envs.tasks.locomotion.basic import crawl_reward, reach_reward, walk_reward
from sirl_jax.envs.tasks.locomotion.obstacles import hurdle_reward, maze_reward, pole_reward
from sirl_jax.envs.tasks.locomotion.sit import sit_reward, yaw_quat
from sirl_jax.envs.tasks.locomotion.terrain import climb_reward

pytestmark = pytest.mark.timeout(120)

G05 = 0.1**0.25  # gaussian tolerance at d = 0.5
INF = math.inf


def close(a, b, tol=1e-5):
    return np.testing.assert_allclose(np.asarray(a), b, rtol=tol, atol=tol)


# -- tolerance ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "x, expected",
    [(0.0, 1.0), (0.5, G05), (-0.5, G05), (1.0, 0.1), (2.0, 1e-4)],
)
def test_tolerance_gaussian(x, expected):
    close(R.tolerance(x, (0.0, 0.0), margin=1.0), expected)


@pytest.mark.parametrize("x, expected", [(2.0, 1.0), (1.0, 1.0), (0.0, 0.5), (-1.0, 0.0), (-5, 0)])
def test_tolerance_linear_one_sided(x, expected):
    close(R.tolerance(x, (1.0, INF), margin=2.0, sigmoid="linear", value_at_margin=0.0), expected)


def test_tolerance_linear_value_at_margin():
    # d = 1 -> vam; d = 2 -> 1 - 2 (1 - 0.5) = 0
    close(R.tolerance(3.0, (0, 1), margin=2.0, sigmoid="linear", value_at_margin=0.5), 0.5)
    close(R.tolerance(5.0, (0, 1), margin=2.0, sigmoid="linear", value_at_margin=0.5), 0.0)


@pytest.mark.parametrize(
    "x, expected", [(5.0, 0.75), (-5.0, 0.75), (10.0, 0.0), (-20, 0.0), (0, 1)]
)
def test_tolerance_quadratic(x, expected):
    close(R.tolerance(x, margin=10.0, sigmoid="quadratic", value_at_margin=0.0), expected)


def test_tolerance_bounds_and_zero_margin():
    close(R.tolerance(0.7, (0.68, 0.72), margin=0.2), 1.0)
    close(R.tolerance(0.68, (0.68, 0.72), margin=0.2), 1.0)
    close(R.tolerance(0.82, (0.68, 0.72), margin=0.2), G05)
    close(R.tolerance(jnp.array([0.5, 1.0, 1.5, -1.5]), (-1.0, 1.0), margin=0.0), [1, 1, 0, 0])


def test_tolerance_rejects_bad_arguments():
    with pytest.raises(ValueError, match="sigmoid"):
        R.tolerance(0.0, margin=1.0, sigmoid="cubic")
    with pytest.raises(ValueError, match="value_at_margin"):
        R.tolerance(0.0, margin=1.0, value_at_margin=0.0)
    with pytest.raises(ValueError, match="bounds"):
        R.tolerance(0.0, (1.0, 0.0))


# -- shared terms ------------------------------------------------------------------------------
def test_shared_terms():
    close(R.standing(1.7), 1.0)
    close(R.standing(1.65 - 0.4125), 0.1)
    close(R.upright(-0.05, 0.9), 0.5)  # 1 - 0.95 / 1.9
    close(R.upright(-1.5, 0.9), 0.0)
    close(R.small_control(jnp.array([5.0, 0.0, 0.0, 0.0])), (4 + 0.9375) / 5)
    close(R.small_control(jnp.full((61,), 100.0)), 0.8)
    close(R.move(0.5, 1.0), 3.5 / 6)
    close(R.move(-3.0, 1.0), 1 / 6)
    close(R.move(7.0, 5.0), 1.0)
    close(R.dont_move(jnp.array([1.0, 0.0])), (G05 + 1) / 2)


def test_any_contact_needs_penetration_and_mask():
    dist = jnp.array([-0.01, 0.02])
    geom = jnp.array([[0, 5], [3, 4]])
    mask = np.zeros(6, bool)
    assert not bool(R.any_contact(dist, geom, jnp.asarray(mask)))
    mask4 = mask.copy()
    mask4[4] = True  # only in the non-penetrating slot
    assert not bool(R.any_contact(dist, geom, jnp.asarray(mask4)))
    mask5 = mask.copy()
    mask5[5] = True
    assert bool(R.any_contact(dist, geom, jnp.asarray(mask5)))
    others = ~mask5
    others0 = others.copy()
    others0[0] = False  # the partner of geom 5 is excluded
    assert bool(R.any_contact(dist, geom, jnp.asarray(mask5), jnp.asarray(others)))
    assert not bool(R.any_contact(dist, geom, jnp.asarray(mask5), jnp.asarray(others0)))


# -- task composites ---------------------------------------------------------------------------
F4 = jnp.array([5.0, 0.0, 0.0, 0.0])  # small_control 0.9875
SC = 0.9875


def test_walk_run_stand():
    v = jnp.array([0.5, 0.0, 0.0])
    r, terms = walk_reward(1.7, -0.05, F4, v, 1.0)
    close(r, SC * 1.0 * 0.5 * 3.5 / 6)
    close(terms["move"], 3.5 / 6)
    r, _ = walk_reward(1.7, -0.05, F4, jnp.array([2.5, 0.0, 0.0]), 5.0)
    close(r, SC * 0.5 * 3.5 / 6)
    r, terms = walk_reward(1.7, -0.05, F4, jnp.array([1.0, 0.0, 0.0]), 0.0)
    close(r, SC * 0.5 * (G05 + 1) / 2)
    assert "dont_move" in terms
    r, _ = walk_reward(1.2375, 1.0, jnp.zeros(4), jnp.array([1.0, 0.0, 0.0]), 1.0)
    close(r, 0.1)


def test_crawl():
    quat = jnp.array([0.75, 0.0, 0.65, 0.0])
    v = jnp.array([1.0, 0.0, 0.0])
    r, _ = crawl_reward(0.8, jnp.array([5.0, 0.5, 1.5]), quat, jnp.zeros(4), v)
    close(r, 0.1 + 0.25 * G05 + 0.4 + 0.25)
    r, _ = crawl_reward(0.8, jnp.array([5.0, 1.5, 1.5]), quat, jnp.zeros(4), v)
    close(r, 0.0)


def test_reach():
    hand = jnp.array([0.0, 0.0, 1.0])
    qvel = jnp.full((75,), 2.0)  # sum of squares 300
    r, _ = reach_reward(1.0, qvel, hand, jnp.array([0.0, 0.0, 1.5]))
    close(r, 5 - 0.03 + 5)
    r, _ = reach_reward(1.0, qvel, hand, jnp.array([0.0, 0.0, 1.02]))
    close(r, 5 - 0.03 + 15)
    r, _ = reach_reward(0.5, qvel, hand, jnp.array([0.0, 2.0, 1.0]))
    close(r, 2.5 - 0.03)


def test_hurdle_and_pole():
    v = jnp.array([2.5, 0.0, 0.0])
    r, _ = hurdle_reward(1.7, 0.8, jnp.zeros(4), v, jnp.array(False))
    close(r, 3.5 / 6)
    r, _ = hurdle_reward(1.7, 0.8, jnp.zeros(4), v, jnp.array(True))
    close(r, 0.35 / 6)
    v = jnp.array([0.25, 0.0, 0.0])
    r, _ = pole_reward(1.7, 1.0, jnp.zeros(4), v, jnp.array(False))
    close(r, 0.5 + 0.5 * 3.5 / 6)
    r, _ = pole_reward(1.7, 1.0, jnp.zeros(4), v, jnp.array(True))
    close(r, 0.1 * (0.5 + 0.5 * 3.5 / 6))


def _maze(pelvis, imu, v, stage, touching=False):
    return maze_reward(
        1.7, 1.0, jnp.zeros(4), jnp.array([*v, 0.0]), jnp.array(pelvis), jnp.array(imu),
        jnp.array(touching), jnp.array(stage, jnp.int32),
    )  # fmt: skip


def test_maze_first_step_bonus_and_stages():
    # Stage 0 -> 1 at the start: +100, direction +x, moving at 2 m/s in x: move 1;
    # proximity to (3, 0) from 2.9 m: 0.1 ** 2.9 ** 2.
    r, stage, terms = _maze((0.1, 0.0), (0.1, 0.0), (2.0, 0.0), 0)
    assert int(stage) == 1
    close(r, 0.2 + 0.4 + 0.4 * 0.1**8.41 + 100.0)
    close(terms["stage_convert_reward"], 100.0)
    # Stage 1, not at (3, 0): v_x 1 is 1 m/s short -> move 1/6; 0.5 m from the checkpoint; wall.
    r, stage, _ = _maze((1.5, 0.0), (2.5, 0.0), (1.0, 0.0), 1, touching=True)
    assert int(stage) == 1
    close(r, 0.1 * (0.2 + 0.4 / 6 + 0.4 * G05))
    # Stage 2 -> 3 at (3, 6): +300, direction +x; stage 3 -> 4 at (6, 6): +400, move = 1.
    r, stage, _ = _maze((3.0, 6.1), (3.0, 6.0), (0.0, 0.0), 2)
    assert int(stage) == 3
    close(r - 300.0, 0.2 + 0.4 * 1 / 6 + 0.4 * 0.1**9)
    r, stage, _ = _maze((6.0, 6.0), (6.0, 6.0), (0.0, 0.0), 3)
    assert int(stage) == 4
    close(r, 0.2 + 0.4 + 0.4 + 400.0)
    # The last stage never advances or pays again.
    r, stage, _ = _maze((6.0, 6.0), (6.0, 6.0), (0.0, 0.0), 4)
    assert int(stage) == 4
    close(r, 1.0)


def test_climb():
    v = jnp.array([1.0, 0.0, 0.0])
    r, terms = climb_reward(1.5, 0.3, 0.75, -0.45, jnp.zeros(4), v)
    close(terms["standing"], 0.1)
    close(terms["upright"], 0.5)
    close(r, 0.05)


def test_sit():
    root = jnp.array([-0.15, 0.05, 0.7])
    chair = jnp.array([-0.25, 0.0])
    r, terms = sit_reward(root, chair, 1.4, 1.0, 0.95, jnp.zeros(4), jnp.zeros(3))
    close(terms["on_chair"], G05)
    close(r, 0.5 + 0.5 * G05)
    r, _ = sit_reward(root, chair, 1.4, 1.0, 0.5, jnp.zeros(4), jnp.zeros(3))
    close(r, 0.5 * (0.5 + 0.5 * G05))  # upright_s = 1 - 0.45 / 0.9


def test_balance():
    r, _ = balance_reward(2.02, 1.0, jnp.zeros(4), jnp.array([0.0, 2.0, 0.0]))
    close(r, 0.55)
    r, _ = balance_reward(1.6075, 1.0, jnp.zeros(4), jnp.zeros(3))
    close(r, 0.1)


def test_yaw_quat():
    close(yaw_quat(jnp.array(0.0)), [1, 0, 0, 0])
    close(yaw_quat(jnp.array(math.pi)), [0, 0, 0, 1], tol=1e-6)
    close(yaw_quat(jnp.array(1.0)), [math.cos(0.5), 0, 0, math.sin(0.5)])
