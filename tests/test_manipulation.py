"""HumanoidBench's manipulation tasks: registry, shapes, tracing and compiled rollouts.

The rewards by hand are in tests/test_manipulation_rewards.py, the contact checks (CPU MuJoCo on
the very model MJX compiles) in tests/test_manipulation_contacts.py. Compiled MJX rollouts
(about a minute each on 2 cores): push and cube in CI, the others marked slow.

Rollouts follow tests/test_tasks.py: E = 4 envs, `reset` then EPISODE + EXTRA steps in a
`lax.scan`, run weightless holding the keyframe pose (nothing falls, so every episode ends by
truncation at exactly EPISODE) and limp (no actuator force, normal gravity).
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
from rollouts import hold_and_limp

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs import TASKS, make
from sirl_jax.envs.physics import OVERFLOW_METRIC

E = 4
EPISODE = 60
EXTRA = 10
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
# CI: push (only success ends it); every other task's rollout, about 2 min each, runs in test-slow.
CI_IDS = ("h1hand-push-v0",)
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
        # the env adds the physics metric where a contact budget can fill (bookshelf, kitchen...)
        physics = {OVERFLOW_METRIC} if env.sim.contact_budget else set()
        assert set(metrics) | physics == set(env.metric_names()), name
        assert jax.tree.structure(task) == jax.tree.structure(state.task), name

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
