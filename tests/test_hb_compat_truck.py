"""HumanoidBench's truck under `hb_compat`: its reward with HumanoidBench's constant 1 by hand on
a constructed state, and its package loops against HumanoidBench's Python loops transcribed on
Python lists, in both modes."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hb_states import forward_c, task_data, task_env

from sirl_jax.envs.tasks.manipulation import truck as T
from sirl_jax.envs.tasks.manipulation.base import body_id
from sirl_jax.hb_compat import HB_COMPAT


# -- truck: the constant 1, package accounting ---------------------------------------------------
@pytest.mark.timeout(120)
@pytest.mark.parametrize("mode", HB_COMPAT)
def test_truck_reward_by_hand_on_a_constructed_state(mode):
    """Torso zz 0.52: upright = 1 - (0.9 - 0.52) / 1.9 = 0.8. The nearest package on the truck
    2.2 m from the root: 1 - (2.2 - 0.2) / 4 = 0.5; the picked-up one 1.0 m from the root: 0.8,
    and 3.4 m from the table body: 0.2; one on the table stays there. No event, so the reward is
    0.8 * (1 + 0.5 + 0.8 + 0.2) = 2.0 in both modes (HumanoidBench's formula, its 1 included)."""
    env = task_env("truck")
    task = env.task.with_hb_compat(mode)
    m = env.mj_model
    d = forward_c(env)
    root = np.array([0.0, 0.0, 1.0])
    where = {"package_a": root + [2.2, 0, 0], "package_b": root + [3.0, 0, 0],
             "package_c": (10.0, 0.0, 1.0), "package_d": root + [0, 1.0, 0],
             "package_e": (2.0, -1.7, 0.95)}  # fmt: skip
    xpos = d.xpos.copy()
    for name, pos in where.items():
        xpos[body_id(m, name)] = pos
    xpos[body_id(m, "table")] = where["package_d"] + np.array([0.0, 3.4, 0.0])
    xmat = np.tile(np.eye(3), (m.nbody, 1, 1))
    xmat[body_id(m, "torso_link"), 2, 2] = 0.52
    qpos = d.qpos.copy()
    qpos[:3] = root
    _, state = task.init(jax.random.PRNGKey(0), jnp.asarray(qpos))
    state = {**state, "status": jnp.array([T.ON_TRUCK] * 3 + [T.PICKED_UP, T.ON_TABLE])}
    data = task_data(d, xpos=xpos, xmat=xmat, qpos=qpos)
    reward, done, state, terms = task.evaluate(env.robot, data, state)
    np.testing.assert_allclose(float(reward), 2.0, atol=1e-5)
    np.testing.assert_allclose([float(terms[k]) for k in ("upright", "reward_robot_package_truck",
                                "reward_robot_package_picked_up", "reward_package_table")],
                               [0.8, 0.5, 0.8, 0.2], atol=1e-5)  # fmt: skip
    assert not bool(done) and np.asarray(state["status"]).tolist() == [0, 0, 0, 1, 2]


def _packages(lifted, upon) -> np.ndarray:
    """[5, 3] package positions: over the table or on the truck, 0.2 up if lifted."""
    return np.array([(2.0, -1.7, 1.1 + 0.2 * l) if u else (5.0, 0.0, 1.1 + 0.2 * l)
                     for l, u in zip(lifted, upon, strict=True)])  # fmt: skip


@functools.cache
def _truck_events(exact: bool):
    """The events of a step (upright 0 and nothing near: the reward is the events alone)."""

    def events(packages, lists, z0):
        far = jnp.array([100.0, 0.0, 1.0])
        return T.truck_reward(jnp.asarray(-1.0), far, -far, packages, lists, z0, exact)[:2]

    return jax.jit(events)


def _truck_rewards(steps, exact: bool) -> list[float]:
    lists, z0, out = T.truck_lists(), None, []
    for lifted, upon in steps:
        packages = _packages(lifted, upon)
        z0 = packages[:, 2] if z0 is None else z0
        r, lists = _truck_events(exact)(jnp.asarray(packages), lists, jnp.asarray(z0))
        out.append(float(r))
    return out


def _hb_truck(steps) -> list[float]:
    """HumanoidBench's `Truck.get_reward` event loops, on Python lists as it runs them, and its
    success bonus."""
    on_truck, picked, on_table, z0, out = [0, 1, 2, 3, 4], [], [], None, []
    for lifted, upon in steps:
        z = _packages(lifted, upon)[:, 2]
        z0 = z if z0 is None else z0
        r = 0
        for p in on_truck:
            if z[p] > z0[p] + 0.1:
                picked.append(p)
                on_truck.remove(p)
                r += 100
        for p in picked:
            if upon[p]:
                on_table.append(p)
                picked.remove(p)
                r += 100
        for p in on_table:
            if not upon[p]:
                on_table.remove(p)
                picked.append(p)
                r -= 100
        out.append(float(r + 1000 * (len(on_table) == 5)))
    return out


@pytest.mark.timeout(120)
def test_truck_loops_skip_the_package_after_a_moved_one_only_in_exact_mode():
    """Packages a, b, d lifted in one step: HumanoidBench's loop moves a, skips b, moves d (+200),
    and b the next step (+100). Over the table: a placed, d skipped, b placed (+200), then d
    (+100). Taken off: a, skips b, d (-200). Fixed mode moves all three each time."""
    none, abd = [0] * 5, [1, 1, 0, 1, 0]
    steps = [(none, none), (abd, none), (abd, none), (abd, abd), (abd, abd), (abd, none)]
    assert _truck_rewards(steps, exact=True) == [0, 200, 100, 200, 100, -200]
    assert _truck_rewards(steps, exact=False) == [0, 300, 0, 300, 0, -300]
    assert _hb_truck(steps) == [0, 200, 100, 200, 100, -200]
    rng = np.random.default_rng(0)
    for _ in range(12):  # random walks against the transcription of HumanoidBench's loops
        steps = [(none, none)] + [(rng.integers(0, 2, 5).tolist(), rng.integers(0, 2, 5).tolist())
                                  for _ in range(7)]  # fmt: skip
        assert _truck_rewards(steps, exact=True) == _hb_truck(steps), steps
