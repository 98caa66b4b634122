"""`export` and `sim2sim`: ONNX policy == JAX prior, exported planner == `agent.plan`, the
contract against the envs' own observations and rewards, a short sim-to-sim run, refusals.

One smoke run (the pendulum, test_cli's flags, so its compiled train step is shared through
the compilation cache) and one export of it serve every test of the module.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from sirl_jax.config import config_to_dict
from sirl_jax.envs import load
from sirl_jax.run import cli, runlog
from sirl_jax.run import contract as C
from sirl_jax.run import contract_sim as S
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.export import flat_params
from sirl_jax.run.sim2sim import load_planner
from sirl_jax.train import make_train

BASE = [
    "--preset", "smoke", "--steps", "650", "--seed-steps", "200", "--chunk-steps", "25",
    "--num-envs", "2", "--eval-every", "650", "--log-every", "50", "--checkpoint-every", "0",
    "--no-progress", "--no-tensorboard",
]  # fmt: skip
STEP = 650


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """(run dir, export dir, Train, the checkpoint's AgentState) of one smoke run."""
    root = tmp_path_factory.mktemp("export")
    run, out = root / "run", root / "out"
    assert cli.main(["train", *BASE, "--run-dir", str(run)]) == 0
    out.mkdir()  # exists: --force writes into it
    assert cli.main(["export", str(run), "--out", str(out), "--force"]) == 0
    config = runlog.load_config(run)
    train = make_train(config, load(config.train.task)[1])
    abstract = jax.eval_shape(train.init, jax.random.PRNGKey(0)).replace(buffer=None)
    ckpt = Checkpointer(run / "checkpoints")
    agent_state = ckpt.restore({"state": abstract}, STEP)["state"].agent
    ckpt.close()
    return run, out, train, agent_state


def _observations(n: int) -> np.ndarray:
    """n pendulum observations: angles all round, velocities up to +-30 rad/s."""
    rng = np.random.default_rng(0)
    theta, vel = rng.uniform(-np.pi, np.pi, n), rng.uniform(-30, 30, n)
    return np.stack([np.cos(theta), np.sin(theta), vel / 10], -1).astype(np.float32)


@pytest.mark.timeout(600)
def test_onnx_policy_equals_the_jax_prior_mean_on_100_observations(exported):
    _, out, train, agent_state = exported
    contract = S.read_contract(out)
    assert contract["files"]["policy.onnx"]["opset"] == 23
    obs = _observations(100)
    onnx_policy = S.onnx_policy(out, contract)
    got = np.stack([onnx_policy(o) for o in obs])
    prior = jax.jit(lambda s, o: train.agent.act_policy(s, o, jax.random.PRNGKey(0), True))
    want = np.asarray(prior(agent_state, obs))
    assert got.shape == want.shape == (100, 1)
    assert np.abs(got - want).max() <= 1e-5
    assert np.ptp(want) > 1e-3  # the actions differ across observations: a real comparison
    saved = dict(np.load(out / "params.npz"))
    flat = flat_params(jax.device_get(agent_state.params))
    assert sorted(saved) == sorted(flat) and "encoder/NormedLinear_0/Dense_0/kernel" in saved
    assert all(np.array_equal(saved[k], flat[k]) for k in flat)


@pytest.mark.timeout(300)
def test_exported_planner_equals_agent_plan_in_eval_mode(exported):
    _, out, train, agent_state = exported
    plan, zero = load_planner(out, S.read_contract(out))
    agent = train.agent
    ref = jax.jit(lambda s, ps, o, f, k: agent.plan(s, ps, o, f, k, eval_mode=True))
    ps, state = agent.init_planner(1), zero
    for t, obs in enumerate(_observations(3)):
        key = jax.random.PRNGKey(10 + t)
        want, ps = ref(agent_state, ps, obs[None], jnp.array([t == 0]), key)
        got, state = plan(jnp.asarray(obs), state, key)
        np.testing.assert_allclose(np.asarray(got), np.asarray(want[0]), rtol=0, atol=1e-6)
        np.testing.assert_allclose(np.asarray(state), np.asarray(ps.prev_mean[0]), rtol=0,
                                   atol=1e-6)  # fmt: skip
    other, _ = plan(jnp.asarray(obs), zero, jax.random.PRNGKey(99))
    assert not np.allclose(np.asarray(other), np.asarray(got))  # the key matters


@pytest.mark.timeout(300)
def test_contract_round_trips_and_names_its_files(exported):
    run, out, train, _ = exported
    contract = S.read_contract(out)
    assert json.loads(json.dumps(contract)) == contract
    config = runlog.load_config(run)
    spec, env = load(config.train.task)
    rebuilt = C.build_contract(env, spec, config_to_dict(config), STEP, out / C.MODEL_FILE)
    assert {k: v for k, v in contract.items() if k != "files"} == rebuilt
    assert contract["training"]["config_sha256"] == C.config_sha256(
        json.loads((out / "config.json").read_text()))  # fmt: skip
    for name, entry in contract["files"].items():
        assert C.sha256_file(out / name) == entry["sha256"], name
    model = S.load_model(out, contract)
    assert (model.nq, model.nu, model.opt.timestep) == (1, 1, 0.01)
    assert contract["timing"] == {"timestep": 0.01, "substeps": 2, "control_dt": 0.02,
                                  "control_hz": 50.0}  # fmt: skip
    assert [a["name"] for a in contract["action"]["actuators"]] == ["torque"]


@pytest.mark.timeout(300)
def test_pendulum_obs_layout_matches_the_env_on_a_constructed_state(exported):
    from mujoco import mjx

    _, out, _, _ = exported
    contract = S.read_contract(out)
    _, env = load("pendulum")
    model = S.load_model(out, contract)
    data = mujoco.MjData(model)
    for qpos, qvel in ((0.7, -3.0), (-2.9, 12.5)):
        data.qpos[:], data.qvel[:] = qpos, qvel
        physics = mjx.make_data(env.mjx_model)
        want = env._obs(physics.replace(qpos=jnp.array([qpos]), qvel=jnp.array([qvel])))
        np.testing.assert_allclose(S.observe(contract, data), np.asarray(want), atol=1e-6)
    assert [f["name"] for f in contract["observation"]["fields"]] == [
        "cos_theta", "sin_theta", "theta_dot/10"]  # fmt: skip


@pytest.mark.timeout(300)
def test_sim2sim_runs_one_short_episode_against_mjx(exported, tmp_path, capsys):
    _, out, _, _ = exported
    figures = tmp_path / "s2s.json"
    argv = ["sim2sim", str(out), "--episodes", "1", "--max-steps", "30", "--json", str(figures)]
    assert cli.main(argv) == 0
    assert "mean |gap|" in capsys.readouterr().out
    (ep,) = json.loads(figures.read_text())["episodes"]
    assert ep["cpu_length"] == ep["mjx_length"] == 30
    assert ep["first_step_obs_diff"] < 1e-4 and abs(ep["return_gap"]) < 0.05
    assert ep["cpu_return"] > 0
    planner = ["sim2sim", str(out), "--episodes", "1", "--max-steps", "3", "--policy", "planner",
               "--no-mjx"]  # fmt: skip
    assert cli.main(planner) == 0


@pytest.mark.timeout(120)
def test_the_cpu_side_imports_no_sirl_jax_env_or_agent_code(exported):
    _, out, _, _ = exported
    code = (
        "import sys\nfrom pathlib import Path\n"
        "from sirl_jax.run import contract_sim as S\n"
        f"d = Path({str(out)!r}); c = S.read_contract(d)\n"
        "m = S.load_model(d, c)\n"
        "init = [S.sample_initial(c, m, __import__('numpy').random.default_rng(0))]\n"
        "(r,) = S.rollout(d, c, S.onnx_policy(d, c), init, 5)\n"
        "assert r['length'] == 5 and r['return'] > 0\n"
        "print(sorted(n for n in sys.modules if n.startswith(('sirl_jax.envs', 'sirl_jax.agent',"
        " 'sirl_jax.train', 'jax'))))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=100, check=True, cwd=Path(__file__).parents[1])  # fmt: skip
    assert proc.stdout.strip() == "[]", proc.stdout


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.timeout(300)
def test_export_refusals_are_one_line(exported, tmp_path, capsys, monkeypatch):
    run, out, _, _ = exported
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(run / "config.json", bare / "config.json")
    capsys.readouterr()
    assert cli.main(["export", str(bare)]) == 2
    assert "has no checkpoint: nothing to export" in _one_error_line(capsys)
    assert sorted(p.name for p in bare.iterdir()) == ["config.json"]
    (bare / "checkpoints").mkdir()
    assert cli.main(["export", str(bare)]) == 2
    assert "has no checkpoint: nothing to export" in _one_error_line(capsys)
    assert cli.main(["export", str(run), "--step", "123", "--out", str(tmp_path / "x")]) == 2
    assert "--step 123: no checkpoint at that env step; available: [650]" in _one_error_line(
        capsys)  # fmt: skip
    before = sorted(p.name for p in out.iterdir())
    assert cli.main(["export", str(run), "--out", str(out)]) == 2
    assert f"output directory {out} exists; pass --force" in _one_error_line(capsys)
    assert sorted(p.name for p in out.iterdir()) == before
    from sirl_jax.envs.classic import PendulumSwingup

    monkeypatch.setattr(PendulumSwingup, "observation_size", property(lambda self: 4))
    assert cli.main(["export", str(run), "--out", str(tmp_path / "y")]) == 2
    line = _one_error_line(capsys)
    assert "observes 4 entries" in line and "the task's obs is not the policy's" in line
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


@pytest.mark.timeout(120)
def test_sim2sim_refusals_are_one_line(exported, tmp_path, capsys):
    _, out, _, _ = exported
    capsys.readouterr()
    assert cli.main(["sim2sim", str(tmp_path)]) == 2
    assert "is not an export directory (no contract.json)" in _one_error_line(capsys)
    assert cli.main(["sim2sim", str(out), "--episodes", "0"]) == 2
    assert "--episodes=0 is invalid" in _one_error_line(capsys)
    assert cli.main(["sim2sim"]) == 2
    assert "needs an export directory or --task NAME" in _one_error_line(capsys)
    assert cli.main(["sim2sim", "--task", "stand"]) == 2
    assert "--policy must be random" in _one_error_line(capsys)
    assert cli.main(["sim2sim", "--task", "nope", "--policy", "random"]) == 2
    assert "unknown task 'nope'" in _one_error_line(capsys)
    tampered = tmp_path / "tampered"
    shutil.copytree(out, tampered)
    blob = bytearray((tampered / "model.mjb").read_bytes())
    blob[-1] ^= 1
    (tampered / "model.mjb").write_bytes(bytes(blob))
    assert cli.main(["sim2sim", str(tampered), "--no-mjx"]) == 2
    assert "model.mjb does not match the SHA-256 in contract.json" in _one_error_line(capsys)
