"""Faults injected and survived: a physics blow-up in one env, a kill mid-checkpoint, a full
disk, a damaged latest checkpoint.

Blow-ups: E = 4 pendulums (50-step episodes) in the seed phase, one env step per call; a wrapper
makes env 1's observation NaN at step 5 of its episode. Expected, worked out from the contract:
env 1 is reset from its own key at that step, its 5 earlier transitions and the bad one never
become a sampleable episode, the other 3 envs are bit-identical to a run without the fault,
and `env/blowups` sums to 1. Checkpoint faults run the real shell on the toy train
(`tests/toys.py`) and the real orbax writer; the disk-full test uses a 1.6 MB tmpfs (needs
root; skipped otherwise) and, always, a writer that raises ENOSPC.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp
import pytest
from toys import ToyTrain, toy_argv

from sirl_jax.agent import AgentConfig
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs.base import ENV_AXIS, Env, VecEnv
from sirl_jax.envs.classic import PendulumSwingup
from sirl_jax.evaluate import _rollout as _eval_rollout
from sirl_jax.evaluate import make_random_evaluate
from sirl_jax.run import cli, progress, runlog, runner
from sirl_jax.run.checkpoint import Checkpointer, CheckpointWriteError
from sirl_jax.train import make_train

E, T, FAULT_ENV, FAULT_STEP, CALLS = 4, 50, 1, 5, 11  # 11 calls: the fault fires once


class NanAt(Env):
    """Wraps an env: env `index` of a `VecEnv` gets a NaN at step `at_step` of each episode,
    in its observation (`where="obs"`) or only in its physics velocity (`where="qvel"`)."""

    def __init__(self, env: Env, at_step: int, index: int, where: str = "obs"):
        self.inner, self.at_step, self.index, self.where = env, at_step, index, where
        self.mj_model = env.mj_model

    observation_size = property(lambda self: self.inner.observation_size)
    action_size = property(lambda self: self.inner.action_size)
    episode_length = property(lambda self: self.inner.episode_length)
    success_bar = property(lambda self: self.inner.success_bar)

    def metric_names(self):
        return self.inner.metric_names()

    def reset(self, key):
        return self.inner.reset(key)

    def step(self, state, action):
        nxt = self.inner.step(state, action)
        hit = (jax.lax.axis_index(ENV_AXIS) == self.index) & (state.step_count == self.at_step)
        if self.where == "obs":
            return nxt.replace(obs=jnp.where(hit, jnp.nan, nxt.obs))
        qvel = jnp.where(hit, jnp.nan, nxt.physics.qvel)
        return nxt.replace(physics=nxt.physics.replace(qvel=qvel))


def _rollout(env: Env):
    """CALLS train steps of one env step each; returns per-call env states, metrics, the end."""
    train_cfg = TrainConfig(task="pendulum", steps=10_000, num_envs=E, chunk_steps=1,
                            seed_steps=1_000, buffer_size=2_000)  # fmt: skip
    train = make_train(Config(agent=AgentConfig.tiny(batch_size=8), train=train_cfg), env)
    state = jax.jit(train.init)(jax.random.PRNGKey(3))
    step = jax.jit(train.step)
    envs, metrics = [state.env], []
    for _ in range(CALLS):
        state, m = step(state)
        envs.append(state.env)
        metrics.append(jax.device_get(m))
    return jax.device_get(envs), metrics, jax.device_get(state)


@pytest.fixture(scope="module")
def blowup_runs():
    clean = _rollout(PendulumSwingup(episode_length=T))
    faulty = _rollout(NanAt(PendulumSwingup(episode_length=T), FAULT_STEP, FAULT_ENV))
    return clean, faulty


@pytest.mark.slow  # 1.7 min: two 2-env rollouts of the fused step
@pytest.mark.timeout(600)
def test_blowup_resets_one_env_and_leaves_the_others_bit_identical(blowup_runs):
    (clean_envs, clean_m, clean_end), (envs, m, end) = blowup_runs
    assert sum(int(x["env/blowups"]) for x in clean_m) == 0
    assert [int(x["env/blowups"]) for x in m] == [0] * FAULT_STEP + [1] + [0] * (CALLS - 6)
    others = [i for i in range(E) if i != FAULT_ENV]
    for clean_env, env in zip(clean_envs, envs, strict=True):
        for a, b in zip(jax.tree.leaves(clean_env), jax.tree.leaves(env), strict=True):
            np.testing.assert_array_equal(np.asarray(a)[others], np.asarray(b)[others])
    buf, clean_buf = end.buffer, clean_end.buffer
    for name in ("obs", "action", "reward", "terminated", "truncated"):
        a, b = getattr(clean_buf, name)[others], getattr(buf, name)[others]
        np.testing.assert_array_equal(a, b)

    # The faulty env after its 6th step: reset from its own key, no episode ended or counted.
    before, after = envs[FAULT_STEP], envs[FAULT_STEP + 1]
    fresh = PendulumSwingup(episode_length=T).reset(
        jax.random.split(before.key[FAULT_ENV])[0])  # VecEnv's key_reset  # fmt: skip
    np.testing.assert_array_equal(after.obs[FAULT_ENV], fresh.obs)
    assert bool(after.blowup[FAULT_ENV]) and bool(after.first[FAULT_ENV])
    assert int(after.step_count[FAULT_ENV]) == 0 and not after.terminated[FAULT_ENV]
    assert np.isnan(after.last_return[FAULT_ENV]) and np.isfinite(after.final_obs).all()
    assert all(int(x["episode/count"]) == 0 for x in m)

    # Its dropped episode's ring space was reused: entries 0..6 are the new episode.
    assert int(buf.write_pos[FAULT_ENV]) == CALLS - FAULT_STEP
    np.testing.assert_array_equal(buf.obs[FAULT_ENV, 0], after.obs[FAULT_ENV])
    assert np.isfinite(buf.obs).all()
    for i in range(E):
        used = int(buf.write_pos[i])
        assert np.isnan(buf.action[i, 0]).all() and np.isnan(buf.reward[i, 0])  # entry 0
        assert np.isfinite(buf.action[i, 1:used]).all() and np.isfinite(buf.reward[i, 1:used]).all()
    assert int(buf.episodes_recorded) == 0 and buf.r_max == -np.inf


@pytest.mark.slow  # 1.6 min: its own env and eval compiles
@pytest.mark.timeout(300)
def test_a_physics_only_blowup_is_caught_and_eval_leaves_that_episode_out():
    """qvel NaN with a finite observation is still a blow-up (the physics check). In eval the
    blown-up episode is counted and left out of the means."""
    clean = PendulumSwingup(episode_length=T)
    faulty = NanAt(clean, 2, 0, where="qvel")
    vec = VecEnv(faulty, 2)
    state = vec.reset(jax.random.PRNGKey(0))
    step = jax.jit(vec.step)
    flags = []
    for _ in range(4):
        state = step(state, jnp.zeros((2, 1)))
        flags.append(np.asarray(state.blowup).tolist())
    assert flags == [[False, False], [False, False], [True, False], [False, False]]
    assert np.isfinite(np.asarray(state.physics.qvel)).all()

    key = jax.random.PRNGKey(5)
    metrics = jax.jit(make_random_evaluate(faulty, 2))(key)
    act = lambda env_state, aux, k: (jax.random.uniform(k, (2, 1), minval=-1.0, maxval=1.0), aux)
    returns = jax.jit(lambda k: _eval_rollout(clean, 2, act, None, k)[0])(key)
    assert int(metrics["eval/random_blowups"]) == 1
    assert float(metrics["eval/random_return"]) == float(returns[1])  # env 1's episode alone
    assert float(metrics["eval/random_return_std"]) == 0.0


def test_blowup_rate_decides_whether_the_run_stops():
    assert progress.failures({"env/blowups": 1.0}, 100, 0.01) == []
    assert progress.failures({"env/blowups": 2.0}, 100, 0.01) == [
        "env/blowups=2 of 100 env steps (> max_blowup_rate=0.01)"
    ]
    assert progress.failures({"env/blowups": 1.0}, 100, 0.0) != []
    assert progress.failures({"env/blowups": 0.0}, 100, 0.0) == []
    with pytest.raises(ValueError, match="train.max_blowup_rate.*-0.5.*in \\[0, 1\\]"):
        TrainConfig(max_blowup_rate=-0.5)


# ---------------------------------------------------------------- the shell (toy train)


def _toy(monkeypatch, toy: ToyTrain) -> None:
    monkeypatch.setattr(runner, "make_train", lambda config, env: toy)


def _error_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("error:")]


@pytest.mark.timeout(120)
def test_blowups_below_the_rate_are_survived_above_it_stop_the_run(monkeypatch, tmp_path, capsys):
    _toy(monkeypatch, ToyTrain(blowups=1, blowups_from=30))  # 1 of 10 env steps = 10%
    run = tmp_path / "ok"
    assert cli.main(toy_argv(run, "--max-blowup-rate", "0.1", steps=60)) == 0
    rows = runlog.read_jsonl(run / "metrics.jsonl")
    assert [r["env/blowups"] for r in rows] == [0, 0, 1, 1, 1, 1]
    capsys.readouterr()

    run = tmp_path / "stop"
    assert cli.main(toy_argv(run, "--max-blowup-rate", "0.05", steps=60)) == 1
    err = capsys.readouterr().err
    (line,) = _error_lines(err)
    assert "env step 30" in line and "env/blowups=1 of 10 env steps" in line
    assert "last good state (env step 20)" in line
    assert Checkpointer(run / "checkpoints").steps() == [20]


_KILLER = """
    import os, signal, sys
    sys.path.insert(0, {tests!r})
    from orbax.checkpoint._src.path import atomicity
    from toys import ToyTrain, toy_argv
    from sirl_jax.run import cli, runner

    runner.make_train = lambda config, env: ToyTrain()
    finalize = atomicity.AtomicRenameTemporaryPath.finalize

    async def killing_finalize(self):
        # The first item of checkpoint 40 is on disk, the rest is not: die here.
        if "/40.orbax-checkpoint-tmp" in str(self.get()):
            os.kill(os.getpid(), signal.SIGKILL)
        return await finalize(self)

    atomicity.AtomicRenameTemporaryPath.finalize = killing_finalize
    sys.exit(cli.main(toy_argv({run!r}, steps=100)))
"""


@pytest.mark.timeout(300)
def test_kill_during_a_checkpoint_write_resumes_from_the_previous(monkeypatch, tmp_path, capsys):
    run = tmp_path / "run"
    script = textwrap.dedent(_KILLER.format(tests=str(Path(__file__).parent), run=str(run)))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=240, env={**os.environ, "JAX_PLATFORMS": "cpu"})  # fmt: skip
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-2000:]
    ckpt = Checkpointer(run / "checkpoints")
    assert ckpt.steps() == [20] and ckpt.partial_writes(), os.listdir(run / "checkpoints")

    _toy(monkeypatch, ToyTrain())
    assert cli.main(["train", "--resume", str(run), "--no-progress", "--no-tensorboard"]) == 0
    out, err = capsys.readouterr()
    assert "resumed from env step 20" in out and "unfinished checkpoint write" in err
    assert ckpt.steps() == [60, 80, 100] and not ckpt.partial_writes()
    rows = runlog.read_jsonl(run / "metrics.jsonl")
    assert [r["env_steps"] for r in rows] == list(range(10, 101, 10))


def _damage(path: Path, how: str) -> None:
    raw = path.read_bytes()
    if how == "flip":
        path.write_bytes(raw[: len(raw) // 2] + bytes([raw[len(raw) // 2] ^ 0xFF])
                         + raw[len(raw) // 2 + 1:])  # fmt: skip
    else:
        path.write_bytes(raw[: len(raw) // 2])


def _largest_file(step_dir: Path) -> Path:
    return max((p for p in step_dir.rglob("*") if p.is_file()), key=lambda p: p.stat().st_size)


@pytest.mark.timeout(180)
@pytest.mark.parametrize("how", ["flip", "truncate"])
def test_damaged_latest_checkpoint_falls_back_to_the_newest_intact(monkeypatch, tmp_path,
                                                                    capsys, how):  # fmt: skip
    _toy(monkeypatch, ToyTrain())
    run = tmp_path / "run"
    assert cli.main(toy_argv(run, "--buffer-size", "40", steps=60)) == 0
    victim = _largest_file(run / "checkpoints" / "60")
    _damage(victim, how)
    damaged_bytes, rel = victim.read_bytes(), victim.relative_to(run / "checkpoints" / "60")
    capsys.readouterr()

    # Asked for by step, the damaged one is an error and nothing is renamed.
    resume = ["train", "--resume", str(run), "--no-progress", "--no-tensorboard"]
    assert cli.main([*resume, "--resume-step", "60"]) == 2
    (line,) = _error_lines(capsys.readouterr().err)
    assert "damaged" in line or "unreadable" in line
    assert (run / "checkpoints" / "60").is_dir()

    assert cli.main([*resume, "--steps", "100"]) == 0
    out, err = capsys.readouterr()
    assert "resumed from env step 40" in out and "newest intact checkpoint, env step 40" in err
    assert (run / "checkpoints" / "60.damaged" / rel).read_bytes() == damaged_bytes  # kept
    assert Checkpointer(run / "checkpoints").steps() == [60, 80, 100]
    rows = runlog.read_jsonl(run / "metrics.jsonl")
    assert [r["env_steps"] for r in rows] == list(range(10, 101, 10))


@pytest.mark.timeout(120)
def test_every_checkpoint_damaged_is_an_error_and_nothing_is_renamed(monkeypatch, tmp_path,
                                                                     capsys):  # fmt: skip
    _toy(monkeypatch, ToyTrain())
    run = tmp_path / "run"
    assert cli.main(toy_argv(run, steps=40)) == 0
    for step in (20, 40):
        _damage(_largest_file(run / "checkpoints" / str(step)), "flip")
    capsys.readouterr()
    assert cli.main(["train", "--resume", str(run), "--no-progress"]) == 2
    (line,) = _error_lines(capsys.readouterr().err)
    assert "every checkpoint" in line and "nothing was renamed" in line
    assert sorted(os.listdir(run / "checkpoints")) == ["20", "40"]


# ---------------------------------------------------------------- a full disk


def _raise_enospc_after_a_partial_write(self, step, *args, **kwargs):
    partial = Path(self.directory) / f"{step}.orbax-checkpoint-tmp-1234"
    partial.mkdir()
    (partial / "half").write_bytes(b"\0" * 100)
    raise OSError(errno.ENOSPC, "No space left on device")


@pytest.mark.timeout(60)
def test_enospc_from_the_writer_is_one_line_and_keeps_the_previous(monkeypatch, tmp_path):
    ckpt = Checkpointer(tmp_path / "ck")
    ckpt.save(1, {"state": {"a": np.arange(5.0)}})
    monkeypatch.setattr(ocp.CheckpointManager, "save", _raise_enospc_after_a_partial_write)
    with pytest.raises(CheckpointWriteError) as e:
        ckpt.save(2, {"state": {"a": np.arange(5.0)}})
    assert "disk full (ENOSPC)" in str(e.value) and "newest intact checkpoint is 1" in str(e.value)
    assert "\n" not in str(e.value)
    assert sorted(os.listdir(tmp_path / "ck")) == ["1"]  # the partial write is removed
    np.testing.assert_array_equal(ckpt.restore({"state": {"a": np.zeros(5)}})["state"]["a"],
                                  np.arange(5.0))  # fmt: skip


@pytest.fixture
def small_disk(tmp_path):
    """A 1.6 MB tmpfs (root only); skipped where it cannot be mounted."""
    mount = tmp_path / "disk"
    mount.mkdir()
    try:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1600k", "tmpfs", str(mount)],
                       check=True, capture_output=True, timeout=30)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        pytest.skip("cannot mount a tmpfs here (needs root); the ENOSPC writer test covers it")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False, timeout=30)


@pytest.mark.timeout(180)
def test_a_full_disk_stops_the_run_cleanly_and_keeps_the_last_checkpoint(monkeypatch, small_disk,
                                                                         capsys):  # fmt: skip
    # 250k random floats: each checkpoint is about 1 MB, so the second one cannot fit.
    toy = ToyTrain(buffer_floats=250_000)
    _toy(monkeypatch, toy)
    run = small_disk / "run"
    assert cli.main(toy_argv(run, steps=100)) == 1
    (line,) = _error_lines(capsys.readouterr().err)
    assert "disk full (ENOSPC)" in line and "newest intact checkpoint is 20" in line, line
    assert "--resume" in line
    ckpt = Checkpointer(run / "checkpoints")
    assert ckpt.steps() == [20] and not ckpt.partial_writes()
    abstract = jax.eval_shape(toy.init, jax.random.PRNGKey(0))
    good = ckpt.restore({"state": abstract.replace(buffer=None), "buffer": abstract.buffer})
    assert int(good["state"].env_steps) == 20
    np.testing.assert_allclose(good["buffer"]["obs"],
                               toy.init(jax.random.PRNGKey(0)).buffer["obs"] + 2.0, rtol=1e-6)
