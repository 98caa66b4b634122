"""HumanoidBench's quirks under one switch, `hb_compat`: the switch's route and its errors, and
each quirk differing between "exact" and "fixed" where it should. Expectations are worked out
by hand here, or come from HumanoidBench's Python loops transcribed on Python lists (truck);
truck's reward (with HumanoidBench's constant 1) is computed by hand on a constructed state.

Fast by design: the task code runs eagerly on compiled MuJoCo models (no jit) or under one small
jit; the MuJoCo models are built once per module.
"""

from __future__ import annotations

import functools
import math
import types

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from hb_states import forward_c, task_data, task_env, task_of

from sirl_jax.config import TrainConfig
from sirl_jax.envs import load, make
from sirl_jax.envs.base import Env, VecEnv, init_state
from sirl_jax.envs.tasks.manipulation import kitchen as K
from sirl_jax.envs.tasks.manipulation import truck as T
from sirl_jax.envs.tasks.manipulation.base import free_joint_adr
from sirl_jax.envs.tasks.manipulation.basketball import CATCH, THROW
from sirl_jax.hb_compat import HB_COMPAT


# -- the switch --------------------------------------------------------------------------------
@pytest.mark.timeout(120)
def test_bad_values_are_refused_naming_the_value_and_the_allowed_ones():
    allowed = r"allowed: one of \('exact', 'fixed'\)"
    assert HB_COMPAT == ("exact", "fixed")
    with pytest.raises(ValueError, match=r"hb_compat='exactly' is invalid; " + allowed):
        load("truck", hb_compat="exactly")
    with pytest.raises(ValueError, match=r"hb_compat='Fixed' is invalid; " + allowed):
        make("kitchen", hb_compat="Fixed")
    with pytest.raises(ValueError, match=r"train.hb_compat='hb' is invalid; " + allowed):
        TrainConfig(hb_compat="hb")
    with pytest.raises(ValueError, match=r"hb_compat=None is invalid; " + allowed):
        task_env("kitchen").task.with_hb_compat(None)


@pytest.mark.timeout(300)
def test_the_switch_reaches_the_task_from_the_cli_and_from_load():
    from sirl_jax.run import cli
    from sirl_jax.run.errors import UsageError
    from sirl_jax.run.runner import load_task

    assert TrainConfig().hb_compat == "exact"
    with pytest.raises(UsageError, match=r"^train.hb_compat='bogus' is invalid; allowed: one of"):
        cli.parse_train_args(["--hb-compat", "bogus"])
    args, _ = cli.parse_train_args(["--task", "kitchen", "--hb-compat", "fixed"])
    assert args.config.train.hb_compat == "fixed"
    _, env = load_task("kitchen", hb_compat=args.config.train.hb_compat)  # what `build` does
    assert env.task.hb_compat == "fixed" and env.task.strict_order
    kitchen = task_env("kitchen").task
    assert kitchen.hb_compat == "exact" and not kitchen.strict_order
    spec, _ = load("pendulum", hb_compat="fixed")  # not HumanoidBench's: accepted, unused
    assert not spec.takes_hb_compat


# -- kitchen: order of work ----------------------------------------------------------------------
@pytest.mark.timeout(120)
def test_kitchen_pays_work_done_early_only_in_exact_mode():
    """The kettle put on its goal before the microwave opens: HumanoidBench pays it with the
    microwave (+2 in that step); fixed mode pays the microwave alone."""
    obj0 = np.array(K.OBJECT_QPOS0, np.float64)

    def done(obj, name):
        obj = obj.copy()
        obj[list(K.SUBTASK_INDICES[name])] = K.SUBTASK_GOALS[name]
        return obj

    kettle = done(obj0, "kettle")
    steps = [obj0, kettle, done(kettle, "microwave")]
    for mode, expected in (("exact", [0.0, 0.0, 2.0]), ("fixed", [0.0, 0.0, 1.0])):
        task = task_of("kitchen", mode)
        state = K.kitchen_init_state(jnp.asarray(obj0, jnp.float32))
        rewards = []
        for obj in steps:
            qpos = jnp.asarray(np.r_[np.zeros(76), obj], jnp.float32)
            r, _, state, _ = task.evaluate(None, types.SimpleNamespace(qpos=qpos), state)
            rewards.append(float(r))
        assert rewards == expected, mode


# -- state carried across resets: truck's lists, spoon's counter ---------------------------------
@pytest.mark.timeout(120)
def test_carry_keeps_the_previous_episode_state_only_in_exact_mode():
    previous = {**T.truck_lists(), "status": jnp.array([1, 2, 0, 0, 0]),
                "z0": jnp.arange(5.0)}  # fmt: skip
    fresh = {**T.truck_lists(), "z0": jnp.full(5, jnp.nan)}
    kept = task_of("truck", "exact").carry(previous, fresh)
    assert np.asarray(kept["status"]).tolist() == [1, 2, 0, 0, 0]
    assert np.asarray(kept["z0"]).tolist() == [0, 1, 2, 3, 4]
    assert task_of("truck", "fixed").carry(previous, fresh) is fresh
    spoon = {"phase": jnp.int32(13), "shown": jnp.int32(12)}
    zero = {"phase": jnp.int32(0), "shown": jnp.int32(0)}
    exact = task_of("spoon", "exact").carry(spoon, zero)
    assert (int(exact["phase"]), int(exact["shown"])) == (13, 13)
    assert task_of("spoon", "fixed").carry(spoon, zero) is zero


class _CarryEnv(Env):
    """Toy env: the task state counts steps; `reset_next` starts from the previous count + 100,
    `reset` from 0. An action > 0.5 ends the episode."""

    observation_size, action_size, episode_length = 1, 1, 50

    def reset(self, key):
        return self._start(key, jnp.int32(0))

    def reset_next(self, key, previous):
        return self._start(key, previous.task + 100)

    def _start(self, key, count):
        return init_state(jnp.zeros(()), jnp.zeros(1), key, task=count)

    def step(self, state, action):
        return state.replace(task=state.task + 1, terminated=action[0] > 0.5)


@pytest.mark.timeout(120)
def test_vecenv_starts_the_next_episode_from_reset_next():
    vec = VecEnv(_CarryEnv(), 2)
    state = jax.jit(vec.reset)(jax.random.PRNGKey(0))
    step = jax.jit(vec.step)
    state = step(state, jnp.array([[0.0], [0.0]]))
    state = step(state, jnp.array([[1.0], [0.0]]))  # env 0 ends its episode after 2 steps
    assert np.asarray(state.task).tolist() == [102, 2]
    assert np.asarray(state.first).tolist() == [True, False]


@pytest.mark.timeout(300)
def test_spoon_reset_after_an_episode_shows_the_carried_phase():
    """HumanoidEnv.reset_next on spoon (exact mode, one compile): the reset observation shows
    the target of the phase the previous episode left (13: angle 13 * 2 pi / 40), and the task
    state starts there (fixed mode's `carry` returns the fresh state: the test above)."""
    env = task_env("spoon")
    previous = types.SimpleNamespace(task={"phase": jnp.int32(13), "shown": jnp.int32(12)})
    a = 13 * 2 * math.pi / 40
    target = np.array([0.75, -0.1, 0.95]) + 0.06 * np.array([math.cos(a), math.sin(a), 0.0])
    reset_next = jax.jit(functools.partial(env.reset_next, previous=previous))
    start = reset_next(jax.random.PRNGKey(0))
    np.testing.assert_allclose(np.asarray(start.obs[-3:]), target, atol=1e-6)
    assert (int(start.task["phase"]), int(start.task["shown"])) == (13, 13)


# -- window and room: start quaternions, reset writes ------------------------------------------
def _noisy_keyframe(env, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    key_qpos = np.asarray(env.mj_model.key_qpos[0], np.float32)
    noise = np.random.default_rng(seed).uniform(-0.01, 0.01, key_qpos.shape).astype(np.float32)
    return jnp.asarray(key_qpos + noise), noise


@pytest.mark.timeout(120)
def test_window_starts_from_zero_quaternions_only_in_exact_mode():
    env = task_env("window")
    m = env.mj_model
    tool = free_joint_adr(m, "free_window_wiping_tool")[0] + 3
    ball = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL]
    assert len(ball) == 1
    quats = [*range(tool, tool + 4), *range(m.jnt_qposadr[ball[0]], m.jnt_qposadr[ball[0]] + 4)]
    qpos_in, noise = _noisy_keyframe(env)
    out = {mode: np.asarray(task_of("window", mode).init(jax.random.PRNGKey(0), qpos_in)[0])
           for mode in HB_COMPAT}  # fmt: skip
    np.testing.assert_allclose(out["exact"][quats], noise[quats], atol=1e-6)  # 0 + noise
    np.testing.assert_allclose(out["fixed"][quats], [1, 0, 0, 0] * 2 + noise[quats], atol=1e-6)
    rest = np.setdiff1d(np.arange(m.nq), quats)
    np.testing.assert_array_equal(out["exact"][rest], out["fixed"][rest])


@pytest.mark.timeout(120)
def test_room_reset_writes_and_quaternions_only_in_exact_mode():
    env = task_env("room")
    m = env.mj_model
    names = ("chair", "trophy", "headphone", "package_a", "package_b", "snow_globe")
    adr = {n: free_joint_adr(m, f"free_{n}")[0] for n in names}
    # HumanoidBench writes x, y of a seventh "object" at qpos[-49], qpos[-48]: the right hand's
    # little finger (qpos 69, 70 of 118)
    assert m.nq == 118
    finger = {m.joint(j).name: int(m.jnt_qposadr[j]) for j in range(m.njnt)}
    assert (finger["rh_LFJ2"], finger["rh_LFJ1"]) == (69, 70)
    headphone = np.array([0.0733422, 0.0519076, -0.240058, -0.966591])
    for seed in range(4):
        qpos_in, noise = _noisy_keyframe(env, seed)
        key = jax.random.PRNGKey(seed)
        exact = np.asarray(task_of("room", "exact").init(key, qpos_in)[0])
        fixed = np.asarray(task_of("room", "fixed").init(key, qpos_in)[0])
        for n in names:
            a = adr[n]
            np.testing.assert_array_equal(exact[a : a + 2], fixed[a : a + 2])  # same x, y
            assert -2.5 + names.index(n) <= fixed[a] <= -1.5 + names.index(n)
            assert 1.2 <= abs(fixed[a + 1]) <= 3.5
            q = slice(a + 3, a + 7)
            if n == "headphone":
                np.testing.assert_allclose(exact[q], headphone, atol=1e-7)  # written after noise
                np.testing.assert_allclose(fixed[q], headphone + noise[q], atol=1e-6)
            else:
                np.testing.assert_allclose(exact[q], noise[q], atol=1e-6)  # (0, 0, 0, 0) + noise
                np.testing.assert_allclose(fixed[q], m.key_qpos[0][q] + noise[q], atol=1e-6)
        assert -3.5 <= exact[69] <= -2.5 and 1.2 <= abs(exact[70]) <= 3.5
        np.testing.assert_array_equal(fixed[69:71], np.asarray(qpos_in)[69:71])  # robot untouched
        np.testing.assert_array_equal(exact[:69], fixed[:69])


@pytest.mark.timeout(120)
def test_room_exact_reset_steps_finite_in_mujoco_c():
    """The thrown finger and the zero-quaternion objects: 0.5 s of MuJoCo C from an exact reset
    stays finite, and the finger is pushed back toward its range (0 to 1.57 rad)."""
    env = task_env("room")
    qpos_in, _ = _noisy_keyframe(env)
    qpos = np.asarray(task_of("room", "exact").init(jax.random.PRNGKey(1), qpos_in)[0], np.float64)
    d = forward_c(env, qpos)
    start = d.qpos[69]
    d.ctrl[:] = np.asarray(env.robot.action_to_ctrl(env.robot.keyframe_action))
    for _ in range(250):
        mujoco.mj_step(env.mj_model, d)
    assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()
    assert d.qpos[69] > start + 1.0


# -- basketball: any ball contact ends the catch stage -------------------------------------------
@pytest.mark.timeout(120)
def test_basketball_ball_on_a_leg_ends_the_catch_stage_only_in_exact_mode():
    """The ball (r 0.1193) centred 0.1 m in front of the left shin's axis overlaps the shin
    capsule, a contact MuJoCo C does not report here (the ball does not touch the legs);
    HumanoidBench's rule (any ball contact) ends the catch stage, fixed mode's does not. Far
    from the robot neither does; an active ball contact (the floor) ends it in both modes."""
    hb = task_env("basketball")  # HumanoidBench's contact set: the ball touches the shin
    env = make("basketball", contact_set="reduced")  # where it does not
    m = env.mj_model
    ball_adr = free_joint_adr(m, "free_basketball")[0]
    ball = m.geom("basketball_collision").id
    d = forward_c(env)
    shin = d.geom("left_shin").xpos.copy()
    qpos = d.qpos.copy()
    qpos[ball_adr : ball_adr + 3] = shin + np.array([0.1, 0.0, 0.0])
    shin_id = hb.mj_model.geom("left_shin").id
    touching = forward_c(hb, qpos)
    assert {shin_id, ball} in [set(pair) for pair in touching.contact.geom[: touching.ncon]]
    d = forward_c(env, qpos)
    assert not (d.contact.geom[: d.ncon] == ball).any()  # no contact with the ball in MuJoCo C
    state = {"stage": jnp.int32(CATCH), "angle": jnp.float32(0.0)}
    stage = {m: int(task_of("basketball", m).evaluate(env.robot, task_data(d), state)[2]["stage"])
             for m in HB_COMPAT}  # fmt: skip
    assert stage == {"exact": THROW, "fixed": CATCH}
    qpos[ball_adr : ball_adr + 3] = (1.5, 0.0, 1.5)
    far = task_data(forward_c(env, qpos))
    for mode in HB_COMPAT:
        assert int(task_of("basketball", mode).evaluate(env.robot, far, state)[2]["stage"]) == CATCH
        floor = types.SimpleNamespace(dist=jnp.array([-1e-3]), geom=jnp.array([[0, ball]]))
        hit = types.SimpleNamespace(**{**vars(far), "contact": floor})
        assert int(task_of("basketball", mode).evaluate(env.robot, hit, state)[2]["stage"]) == THROW


# -- insert_small: the peg_b site ------------------------------------------------------------------
@pytest.mark.timeout(120)
def test_insert_peg_sites_at_humanoidbench_heights():
    """HumanoidBench's XMLs: insert_normal's peg sites 0.01 above the peg origin; insert_small's
    peg_a 0.005 and peg_b 0.01."""
    for name, (z_a, z_b) in (("insert_normal", (0.01, 0.01)), ("insert_small", (0.005, 0.01))):
        m = task_env(name).mj_model
        np.testing.assert_allclose(m.site("peg_a").pos, (0, 0, z_a), atol=1e-9)
        np.testing.assert_allclose(m.site("peg_b").pos, (0, 0, z_b), atol=1e-9)
