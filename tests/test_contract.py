"""The export contract against the envs themselves, without an export: h1hand's observation
layout, reward and termination, the reach and sit_hard resets, balance's contact termination,
and sim2sim's random policy scored by the task and by the contract."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from sirl_jax.envs import load
from sirl_jax.run import contract as C
from sirl_jax.run import contract_sim as S


@pytest.mark.timeout(300)
def test_h1hand_contract_obs_layout_reward_and_termination_match_the_env(tmp_path):
    from mujoco import mjx

    from sirl_jax.envs import h1

    spec, env = load("h1hand-stand-v0")
    C.write_model(env, tmp_path / C.MODEL_FILE)
    contract = C.build_contract(env, spec, {"x": 1}, 0, tmp_path / C.MODEL_FILE)
    fields = contract["observation"]["fields"]
    assert contract["observation"]["size"] == env.observation_size == 151
    names = [f["joint"] for f in fields if f["source"] == "qpos"]
    assert names == ["free_base", *h1.JOINT_NAMES]
    assert [f["start"] for f in fields if f["source"] == "qpos"] == [0, *range(7, 76)]
    assert [f["start"] for f in fields if f["source"] == "qvel"] == [76, *range(82, 151)]
    assert [a["name"] for a in contract["action"]["actuators"]] == list(h1.ACTUATOR_NAMES)
    assert contract["timing"]["substeps"] == h1.N_SUBSTEPS
    assert contract["termination"] == {"kind": "qpos_below", "adr": 2, "value": 0.2,
                                       "rule": "root z < 0.2"}  # fmt: skip
    model = S.load_model(tmp_path, contract)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    qpos, qvel, values = S.sample_initial(contract, model, rng)
    assert values == {} and "then" not in contract["reset"]
    data.qpos[:], data.qvel[:] = qpos, qvel + rng.normal(0, 0.3, model.nv)
    mujoco.mj_forward(model, data)
    want = env._observe(mjx.put_data(model, data), ())
    np.testing.assert_allclose(S.observe(contract, data), np.asarray(want), atol=1e-6)
    action = rng.uniform(-1, 1, model.nu)
    data.ctrl[:] = S.to_ctrl(contract, action)
    np.testing.assert_allclose(data.ctrl, np.asarray(env.robot.action_to_ctrl(action)),
                               atol=1e-5)  # fmt: skip
    for _ in range(h1.N_SUBSTEPS):
        mujoco.mj_step(model, data)
    d = mjx.put_data(model, data)
    reward, done, _, _ = env.task.evaluate(env.robot, d, ())
    assert abs(S.reward(contract, model, data, action) - float(reward)) < 1e-5
    assert S.terminated(contract, model, data) == bool(done)
    from sirl_jax.envs.tasks.locomotion.basic import walk_reward

    r, vx = env.robot, model.sensor("pelvis_subtreelinvel").adr[0]
    for speed in (1.0, 5.0):  # walk and run: the move branch, v_x inside the margin
        data.sensordata[vx] = speed - 0.3
        d = mjx.put_data(model, data)
        want, _ = walk_reward(r.head_height(d), r.torso_upright(d), r.actuator_forces(d),
                              r.com_velocity(d), speed)  # fmt: skip
        moving = {**contract, "reward": {**contract["reward"], "speed": speed}}
        assert abs(S.reward(moving, model, data, action) - float(want)) < 1e-5


@pytest.mark.timeout(300)
def test_reach_and_sit_hard_resets_and_reach_obs_follow_the_contract(tmp_path):
    """The task-randomised resets are contract ops: reach's goal (a drawn value the observation
    reads) and sit_hard's root pose; the obs layout equals the env's on a constructed state."""
    from mujoco import mjx

    spec, env = load("h1hand-reach-v0")
    C.write_model(env, tmp_path / C.MODEL_FILE)
    contract = C.build_contract(env, spec, None, 0, tmp_path / C.MODEL_FILE)
    assert contract["training"] is None and contract["termination"]["kind"] == "never"
    assert contract["reset"]["then"] == [{"op": "value_uniform", "name": "goal",
                                          "low": [-2.0, -2.0, 0.2], "high": [2.0, 2.0, 2.0]}]
    assert [f["source"] for f in contract["observation"]["fields"][-2:]] == ["site_xpos",
                                                                             "reset_value"]
    model = S.load_model(tmp_path, contract)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    goals = []
    for _ in range(20):
        qpos, qvel, values = S.sample_initial(contract, model, rng)
        goals.append(values["goal"])
    goals = np.stack(goals)
    assert (goals >= [-2, -2, 0.2]).all() and (goals <= [2, 2, 2]).all() and np.ptp(goals) > 1
    data.qpos[:], data.qvel[:] = qpos, qvel + rng.normal(0, 0.3, model.nv)
    mujoco.mj_forward(model, data)
    goal = env.task.reset_state(values, jnp.asarray(qpos))
    want = env._observe(mjx.put_data(model, data), goal)
    got = S.observe(contract, data, values)
    np.testing.assert_allclose(got, np.asarray(want), atol=1e-6)
    np.testing.assert_allclose(got[-3:], values["goal"], atol=1e-6)
    with pytest.raises(S.ContractError, match="reset value 'goal'"):
        S.observe(contract, data, {})

    spec, env = load("h1hand-sit_hard-v0")
    C.write_model(env, tmp_path / C.MODEL_FILE)
    contract = C.build_contract(env, spec, None, 0, tmp_path / C.MODEL_FILE)
    (op,) = contract["reset"]["then"]
    assert (op["op"], op["x"], op["y"], op["yaw"]) == ("root_pose_uniform", [0.2, 0.4],
                                                       [-0.15, 0.15], [-1.8, 1.8])
    model = S.load_model(tmp_path, contract)
    poses = np.stack([S.sample_initial(contract, model, rng)[0] for _ in range(50)])
    yaw = 2 * np.arctan2(poses[:, 6], poses[:, 3])
    assert (poses[:, 0] >= 0.2).all() and (poses[:, 0] <= 0.4).all()
    assert (np.abs(poses[:, 1]) <= 0.15).all() and (np.abs(yaw) <= 1.8).all()
    assert np.ptp(yaw) > 2.0 and np.allclose(poses[:, 4:6], 0.0)
    # the task's own randomisation lands in the same box (one distribution, two samplers)
    q0 = jnp.asarray(model.key_qpos[0], jnp.float32)
    env_q = np.asarray(jax.vmap(lambda k: env.task.init(k, q0)[0])(
        jax.random.split(jax.random.PRNGKey(0), 50)))  # fmt: skip
    assert (env_q[:, 0] >= 0.2).all() and (env_q[:, 0] <= 0.4).all() and np.ptp(env_q[:, 0]) > 0.1

    # push places its goal from task code: refused, with the reason; cabinet's init draws
    # nothing (its stage starts at 1), so its reset is the plain noisy keyframe
    for name, described in (("h1hand-push-v0", False), ("h1hand-cabinet-v0", True)):
        spec, env = load(name)
        C.write_model(env, tmp_path / C.MODEL_FILE)
        contract = C.build_contract(env, spec, None, 0, tmp_path / C.MODEL_FILE)
        model = S.load_model(tmp_path, contract)
        if described:
            assert contract["reset"]["kind"] == "keyframe_noise"
            assert len(S.sample_initial(contract, model, rng)[0]) == model.nq
        else:
            with pytest.raises(S.ContractError, match="PushTask's reset does what the contract"):
                S.sample_initial(contract, model, rng)


@pytest.mark.timeout(300)
def test_balance_contact_termination_in_the_contract_equals_the_task(tmp_path):
    """balance_hard's termination as contract rules (root z, robot-sphere overlap, robot or
    board below the floor), read by MuJoCo C's mj_geomDistance, against the task's own rule
    on constructed states."""
    from mujoco import mjx

    spec, env = load("h1hand-balance_hard-v0")
    C.write_model(env, tmp_path / C.MODEL_FILE)
    contract = C.build_contract(env, spec, None, 0, tmp_path / C.MODEL_FILE)
    rule = contract["termination"]
    assert rule["kind"] == "any" and [r["kind"] for r in rule["rules"]] == [
        "qpos_below", "geoms_overlap", "geoms_overlap"]  # fmt: skip
    assert "lh_mfdistal" in rule["rules"][1]["a"] and len(rule["rules"][1]["a"]) > 80
    model = S.load_model(tmp_path, contract)
    data = mujoco.MjData(model)
    evaluate = jax.jit(lambda d: env.task.evaluate(env.robot, d, ())[1])
    hand = model.geom("lh_mfdistal")
    sphere = model.joint("free_rolling_pivot").qposadr[0]
    board = model.joint("free_stand_board").qposadr[0]

    def both(edit) -> tuple[bool, bool]:
        data.qpos[:] = model.key_qpos[0]
        mujoco.mj_kinematics(model, data)
        edit()
        mujoco.mj_forward(model, data)
        return S.terminated(contract, model, data), bool(evaluate(mjx.put_data(model, data)))

    def into_hand():  # the sphere's surface 1 cm inside the fingertip's centre
        mujoco.mj_kinematics(model, data)
        centre = data.geom_xpos[hand.id] + np.array([0.0, 0.0, 0.17 - 0.01])
        data.qpos[sphere:sphere + 3] = centre

    def board_down():
        data.qpos[board + 2] = 0.01  # half-height 0.03: 2 cm below the floor

    def root_low():
        data.qpos[2] = 0.7

    assert both(lambda: None) == (False, False)
    assert both(into_hand) == (True, True)
    assert both(board_down) == (True, True)
    assert both(root_low) == (True, True)


@pytest.mark.timeout(300)
def test_sim2sim_random_policy_cpu_return_scored_by_the_task_equals_the_contract_reward():
    """sim2sim --task stand --policy random --no-mjx: the CPU return scored by the task's own
    reward on the recorded CPU states equals the contract's numpy reward, and the task's
    termination (root z) ends the episode where the contract's did, through the robot's fall
    (the upright and standing terms fall with it, so every recorded field they read counts)."""
    from sirl_jax.run.sim2sim import sim2sim

    result = sim2sim(None, 2, "random", 150, 0, mjx=False, task="stand")
    assert result["cpu_return_source"] == "task" and result["task"] == "h1hand-stand-v0"
    for ep in result["episodes"]:
        assert ep["cpu_terminated"] and ep["cpu_length"] < 150  # a random policy falls
        assert ep["cpu_loop_length"] == ep["cpu_length"] and ep["termination_agrees"]
        assert abs(ep["cpu_return"] - ep["cpu_contract_return"]) < 1e-5 * ep["cpu_length"]
        assert ep["cpu_return"] > 0.1
