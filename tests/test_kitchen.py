"""HumanoidBench Kitchen (`sirl_jax/envs/tasks/manipulation/kitchen.py`): sizes, the subtask
reward and its order, the articulated furniture (CPU MuJoCo on the model MJX compiles). The
compiled MJX rollout is `tests/test_manipulation.py::test_rollout[h1hand-kitchen-v0]` (slow)."""

from __future__ import annotations

import copy
import types

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from sirl_jax.envs import make
from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.envs.tasks.manipulation import kitchen as K
from sirl_jax.envs.tasks.manipulation import kitchen_scene as KS
from sirl_jax.envs.tasks.manipulation.kitchen import KitchenTask, kitchen_init_state, kitchen_reward

NQ_ROBOT = 76


@pytest.fixture(scope="module")
def env() -> HumanoidEnv:
    return make("kitchen")


def _obj0() -> np.ndarray:
    return np.array(K.OBJECT_QPOS0, np.float64)


def _done(obj: np.ndarray, name: str, offset: float = 0.0) -> np.ndarray:
    """`obj` with subtask `name` at its goal, its first entry moved by `offset`."""
    obj = obj.copy()
    idx = list(K.SUBTASK_INDICES[name])
    obj[idx] = K.SUBTASK_GOALS[name]
    obj[idx[0]] += offset
    return obj


def _run(objs, strict_order: bool) -> tuple[list[float], dict]:
    """Rewards of a sequence of object qpos [21] and the final task state."""
    state = kitchen_init_state(jnp.asarray(objs[0], jnp.float32))
    rewards = []
    for obj in objs:
        reward, state, _ = kitchen_reward(jnp.asarray(obj, jnp.float32), state, strict_order)
        rewards.append(float(reward))
    return rewards, state


def _hb_reference(objs) -> list[float]:
    """HumanoidBench's rule, written out: scan the remaining subtasks in order; one within
    threshold counts if every remaining one before it is within threshold now; remove those."""
    remaining, rewards = list(K.SUBTASKS), []
    for obj in objs:
        done, all_so_far = [], True
        for name in remaining:
            idx = list(K.SUBTASK_INDICES[name])
            ok = np.linalg.norm(obj[idx] - np.array(K.SUBTASK_GOALS[name])) < K.BONUS_THRESH
            if ok and all_so_far:
                done.append(name)
            all_so_far = all_so_far and ok
        remaining = [n for n in remaining if n not in done]
        rewards.append(float(len(done)))
    return rewards


# -- sizes ----------------------------------------------------------------------------------
@pytest.mark.timeout(300)
def test_sizes_and_reset(env):
    m = env.mj_model
    assert (m.nq, m.nv) == (97, 95)
    assert env.observation_size == 97 and env.action_size == 61
    assert jax.eval_shape(env.reset, jax.random.PRNGKey(0)).obs.shape == (97,)
    key_qpos = m.key_qpos[0]
    np.testing.assert_allclose(key_qpos[NQ_ROBOT:], K.OBJECT_QPOS0)
    np.testing.assert_allclose(key_qpos[:3], (0.0, -0.6, 0.98))
    np.testing.assert_allclose(key_qpos[3:7], np.array([1, 0, 0, 1.57]) / np.hypot(1, 1.57))
    np.testing.assert_allclose(key_qpos[7:17], (0, 0, -0.4, 0.8, -0.4) * 2)
    assert not key_qpos[17:NQ_ROBOT].any()
    # The object qpos layout HumanoidBench's indices assume (object qpos index: joint).
    names = {int(m.jnt_qposadr[j]) - NQ_ROBOT: m.joint(j).name for j in range(m.njnt)}
    assert [names[i] for i in (0, 1, 2, 3, 6, 7, 8, 9, 10, 11, 12, 13, 14)] == [
        "knob_Joint_1", "burner_Joint_1", "knob_Joint_2", "burner_Joint_2", "knob_Joint_4",
        "burner_Joint_4", "lightswitch_joint", "light_joint", "slidedoor_joint",
        "leftdoorhinge", "rightdoorhinge", "microjoint", "free_kettle",
    ]  # fmt: skip
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    np.testing.assert_allclose(np.asarray(state.obs), key_qpos.astype(np.float32))  # no noise
    assert int(state.task["next"]) == 0 and bool(state.task["armed"])


@pytest.mark.timeout(60)
def test_masses(env):
    m = env.mj_model
    for body, mass in (("kettle", 0.88), ("microdoorroot", 0.26), ("knob 2", 0.02),
                       ("lightswitchroot", 0.1), ("slidelink", 0.34), ("hingeleftdoor", 0.34),
                       ("Burner 2", 0.01)):  # fmt: skip
        np.testing.assert_allclose(m.body_subtreemass[m.body(body).id], mass, rtol=1e-6)


# -- reward ---------------------------------------------------------------------------------
@pytest.mark.timeout(60)
@pytest.mark.parametrize("strict_order", [True, False])
def test_each_subtask_completes_at_its_threshold(strict_order):
    obj = _obj0()
    for k, name in enumerate(K.SUBTASKS):
        before = {"next": jnp.int32(k), "armed": jnp.bool_(True)}
        for offset, paid in ((0.29, 1.0), (0.31, 0.0), (-0.29, 1.0), (-0.31, 0.0)):
            reward, state, terms = kitchen_reward(jnp.asarray(_done(obj, name, offset)), before,
                                                  strict_order)  # fmt: skip
            assert float(reward) == paid, (name, offset)
            assert int(state["next"]) == k + int(paid)
            distance = terms[f"{name.replace(' ', '_')}_distance"]
            np.testing.assert_allclose(distance, abs(offset), atol=1e-6)
        obj = _done(obj, name)
    # The microwave hinge: -0.46 (distance 0.29) completes, -0.44 (0.31) does not.
    for q, paid in ((-0.46, 1.0), (-0.44, 0.0)):
        o = _obj0()
        o[13] = q
        assert _run([_obj0(), o], strict_order)[0] == [0.0, paid]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("strict_order", [True, False])
def test_in_order_paid_once_and_terminates(strict_order):
    o0 = _obj0()
    o1 = _done(o0, "microwave")
    o2 = _done(o1, "kettle")
    o3 = _done(o2, "bottom burner")
    o4 = _done(o3, "light switch")
    objs = [o0, o1, o1, o2, o2, o3, o4]
    rewards, state = _run(objs, strict_order)
    assert rewards == [0, 1, 0, 1, 0, 1, 1]
    assert int(state["next"]) == 4
    # An earlier subtask undone after its completion costs nothing and pays nothing again.
    rewards, _ = _run([o0, o1, _done(o0, "kettle"), o2], strict_order)
    assert rewards == [0, 1, 1, 0]
    # Termination (and the metrics) through the task's evaluate.
    task = KitchenTask().with_hb_compat("fixed" if strict_order else "exact")
    assert task.strict_order == strict_order
    state = kitchen_init_state(jnp.asarray(o0, jnp.float32))
    ends, successes = [], []
    for obj in objs:
        data = types.SimpleNamespace(qpos=jnp.asarray(np.r_[np.zeros(NQ_ROBOT), obj]))
        _, terminated, state, terms = task.evaluate(None, data, state)
        ends.append(bool(terminated))
        successes.append(float(terms["success"]))
        assert set(terms) == set(task.metric_names)
    assert ends == [False] * 6 + [True] and successes == ends


@pytest.mark.timeout(60)
def test_out_of_order_humanoidbench_pays_late():
    """HumanoidBench's rule: a kettle on its goal before the microwave opens is paid in the step
    the microwave opens (+2 in one step), and all four chores done in reverse order earn 4."""
    o0 = _obj0()
    kettle = _done(o0, "kettle")
    both = _done(kettle, "microwave")
    objs = [o0, kettle, kettle, both, both]
    assert _run(objs, strict_order=False)[0] == [0, 0, 0, 2, 0] == _hb_reference(objs)
    reverse = [o0]
    for name in reversed(K.SUBTASKS):
        reverse.append(_done(reverse[-1], name))
    assert _run(reverse, strict_order=False)[0] == [0, 0, 0, 0, 4] == _hb_reference(reverse)


@pytest.mark.timeout(60)
def test_out_of_order_strict_needs_a_redo():
    """strict_order=True: a subtask done before its turn is not paid when its turn comes; it is
    paid once it has left its threshold and entered it again. At most one subtask per step."""
    o0 = _obj0()
    kettle = _done(o0, "kettle")
    both = _done(kettle, "microwave")
    micro = _done(o0, "microwave")
    rewards, state = _run([o0, kettle, both, both, micro, both, both], strict_order=True)
    assert rewards == [0, 0, 1, 0, 0, 1, 0] and int(state["next"]) == 2
    everything = o0
    for name in K.SUBTASKS:
        everything = _done(everything, name)
    rewards, state = _run([o0, everything, everything], strict_order=True)
    assert rewards == [0, 1, 0] and int(state["next"]) == 1
    # A microwave already open at reset must be closed and opened again.
    rewards, _ = _run([micro, micro, o0, micro], strict_order=True)
    assert rewards == [0, 0, 0, 1]


@pytest.mark.timeout(120)
def test_humanoidbench_mode_matches_the_reference():
    """strict_order=False against HumanoidBench's loop on random walks through the subtasks."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        objs, obj = [], _obj0()
        for _ in range(12):
            name = K.SUBTASKS[rng.integers(4)]
            obj = _done(obj, name, rng.choice([0.0, 0.5])) if rng.random() < 0.7 else _obj0()
            objs.append(obj)
        assert _run(objs, strict_order=False)[0] == _hb_reference(objs)


# -- articulation (CPU MuJoCo) ----------------------------------------------------------------
def _pinned(env: HumanoidEnv) -> mujoco.MjModel:
    """The env's model with the robot 1000 times heavier: pinned (qpos reset every step), its
    hand then pushes like a kinematic body. With its real link masses the contact impulse goes
    mostly into the light finger links, which cannot beat the door's frictionloss (2 N m)."""
    m = copy.deepcopy(env.mj_model)
    robot = m.body_rootid == m.body("pelvis").id
    m.body_mass[robot] *= 1e3
    m.body_inertia[robot] *= 1e3
    return m


def _drive(m, d, nq, nv, pose, velocity, steps) -> None:
    """Moves the pinned robot's root at `velocity` (m/s) for `steps` physics steps."""
    for _ in range(steps):
        pose[:3] += velocity * m.opt.timestep
        d.qpos[:nq], d.qvel[:nv] = pose, 0.0
        d.qvel[:3] = velocity
        mujoco.mj_step(m, d)


@pytest.mark.timeout(120)
def test_hand_pulls_the_microwave_open():
    """The left fingers hooked behind the microwave's handle bar (hand turned on its side, the
    fingers along the door), then pulled straight out at 0.2 m/s for 1.6 s: the door swings
    open past the completion threshold (-0.45) toward the goal (-0.75); with the hand colliders
    off it stays shut. The kettle rests on its burner meanwhile. The "reduced" contact set: the
    hand is placed by moving the whole robot, turned on its side, whose body then lies inside
    the counters, which in HumanoidBench's set ("hb") it touches."""
    env = make("kitchen", contact_set="reduced")
    m = _pinned(env)
    nq, nv = env.robot.nq_robot, env.robot.nv_robot
    micro = m.joint("microjoint").qposadr[0]
    for hands_on in (True, False):
        if not hands_on:
            m.geom_conaffinity[env.robot.geom_ids["hands"]] = 0
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        mujoco.mju_mulQuat(d.qpos[3:7], np.array(KS._quat((0, 0, KS.MICROWAVE_YAW))),
                           np.array(KS._quat((np.pi / 2, 0, 0))))  # fmt: skip
        mujoco.mj_forward(m, d)
        door_pos, door_mat = d.body("microdoorroot").xpos.copy(), d.body("microdoorroot").xmat
        behind_bar = door_pos + door_mat.reshape(3, 3) @ np.array([0.47, -0.069, 0.0])
        d.qpos[:3] += behind_bar - d.geom("lh_mfdistal").xpos
        out = np.array([np.sin(KS.MICROWAVE_YAW), -np.cos(KS.MICROWAVE_YAW), 0.0])
        _drive(m, d, nq, nv, d.qpos[:nq].copy(), 0.2 * out, 800)
        q = d.qpos[micro]
        assert (q < -0.5) if hands_on else (abs(q) < 1e-3), q
        assert abs(d.body("kettle").xpos[2] - KS.KETTLE_POS[2]) < 0.01


@pytest.mark.timeout(120)
def test_hand_turns_the_bottom_burner_knob(env):
    """A fingertip pushed in +x against the top of knob 2's bar turns it (q < 0, toward the
    goal -0.88) and the burner follows at 1/174 (the joint equality)."""
    m = _pinned(env)
    nq, nv = env.robot.nq_robot, env.robot.nv_robot
    knob, burner = m.joint("knob_Joint_2").qposadr[0], m.joint("burner_Joint_2").qposadr[0]
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.qpos[3:7] = (1.0, 0.0, 0.0, 0.0)  # fingers along +x
    mujoco.mj_forward(m, d)
    d.qpos[:3] += d.body("knob 2").xpos + (-0.06, -0.038, 0.025) - d.geom("lh_mfdistal").xpos
    _drive(m, d, nq, nv, d.qpos[:nq].copy(), np.array([0.1, 0.0, 0.0]), 300)
    assert -1.18 < d.qpos[knob] < -0.58, d.qpos[knob]  # within 0.3 of -0.88
    np.testing.assert_allclose(d.qpos[burner] * KS.KNOB_PER_BURNER, d.qpos[knob], atol=0.02)


@pytest.mark.timeout(120)
def test_kettle_rests_on_its_burner(env):
    """Released at the keyframe, the kettle settles on the stove top (z 0.9934) over the bottom
    left burner and stays there for 1 s (robot pinned, real masses)."""
    m = env.mj_model
    nq, nv = env.robot.nq_robot, env.robot.nv_robot
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    pose = d.qpos[:nq].copy()
    zs = []
    for _ in range(500):
        d.qpos[:nq], d.qvel[:nv] = pose, 0.0
        mujoco.mj_step(m, d)
        zs.append(d.body("kettle").xpos[2])
    assert max(abs(z - KS.KETTLE_POS[2]) for z in zs) < 0.01
    np.testing.assert_allclose(d.body("kettle").xpos[:2], KS.KETTLE_POS[:2], atol=1e-3)
    burner = d.body("Burner 2").xpos
    assert np.linalg.norm(d.body("kettle").xpos[:2] - burner[:2]) < 0.05
