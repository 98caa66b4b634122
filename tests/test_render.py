"""`render`: headless GL selection, MJX -> MuJoCo state copies, and a real clip in CI."""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys

import jax
import numpy as np
import pytest

from sirl_jax.run.errors import UsageError
from sirl_jax.run.render import copy_state, select_gl


def test_select_gl_keeps_a_user_choice_and_names_a_missing_package(monkeypatch):
    env = {"MUJOCO_GL": "egl"}
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: f"lib{name}.so")
    assert select_gl(env) == "egl" and env["PYOPENGL_PLATFORM"] == "egl"
    monkeypatch.setattr(os.path, "exists", lambda p: False)  # no NVIDIA device
    env = {}
    assert select_gl(env) == "osmesa" and env["MUJOCO_GL"] == "osmesa"
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    with pytest.raises(UsageError, match="install the system package libosmesa6"):
        select_gl({})
    with pytest.raises(UsageError, match="libEGL.*libegl1"):
        select_gl({"MUJOCO_GL": "egl"})


@pytest.mark.timeout(300)
def test_mjx_state_copied_into_mujoco_gives_the_same_body_positions():
    """A randomised H1 reset (keyframe + qpos noise, kinematics in MJX): the qpos/qvel copied
    into a CPU MjData of the same scene and forwarded reproduce MJX's xpos."""
    import mujoco

    from sirl_jax.envs import load

    _, env = load("h1-walk-v0")
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(3), 2))
    data = mujoco.MjData(env.mj_model)
    for i in range(2):
        d = jax.tree.map(lambda x, i=i: np.asarray(x[i]), env.mjx_data(state.physics))
        copy_state(env.mj_model, data, d.qpos, d.qvel)
        assert np.abs(d.qpos - env.mj_model.key_qpos[0]).max() > 1e-3  # the noise is there
        np.testing.assert_allclose(data.xpos, d.xpos, atol=2e-5)


@pytest.mark.timeout(600)
def test_random_clip_is_written_headless(tmp_path):
    """The CLI end to end in a fresh process (MuJoCo must see MUJOCO_GL at import)."""
    imageio = pytest.importorskip("imageio.v2")
    out = tmp_path / "clip.mp4"
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    cmd = [sys.executable, "-m", "sirl_jax", "render", "--random", "--task", "pendulum",
           "--episodes", "2", "--max-steps", "12", "--width", "160", "--height", "120",
           "--out", str(out)]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=540, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "24 frames (160x120" in proc.stdout, proc.stdout
    frames = np.stack([f for f in imageio.get_reader(out, format="FFMPEG")])  # len() is inf
    assert frames.shape == (24, 120, 160, 3)
    scene = frames[:, 24:].astype(np.int16)  # below the caption bar
    assert np.abs(scene[0] - scene[-1]).max() > 30  # the pendulum moved
    assert len({f.tobytes() for f in frames}) == 24


def test_render_refuses_bad_input(capsys, monkeypatch):
    from sirl_jax.run import cli, render

    monkeypatch.setattr(render, "select_gl", lambda: "osmesa")  # no change to this process

    for argv, needle in (
        (["render"], "give a RUN_DIR, or --random with --task NAME"),
        (["render", "/no/such/run"], "does not exist"),
        (["render", "--random", "--task", "pendulum", "--width", "0"], "--width=0 is invalid"),
    ):
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: ") and needle in err and "\n" not in err, err
