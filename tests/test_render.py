"""`render`: headless GL selection, MJX -> MuJoCo state copies, and a real clip in CI."""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys

import jax
import numpy as np
import pytest

from sirl_jax.run import camera
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


def test_render_refuses_bad_input(capsys, monkeypatch, tmp_path):
    import json

    from sirl_jax.config import config_to_dict
    from sirl_jax.presets import get_preset
    from sirl_jax.run import cli, render

    monkeypatch.setattr(render, "select_gl", lambda: "osmesa")  # no change to this process
    untrained = tmp_path / "run"
    untrained.mkdir()
    (untrained / "config.json").write_text(json.dumps(config_to_dict(get_preset("smoke"))))

    for argv, needle in (
        (["render"], "give a RUN_DIR, or --random with --task NAME"),
        (["render", "/no/such/run"], "does not exist"),
        (["render", "--random", "--task", "pendulum", "--width", "0"], "--width=0 is invalid"),
        (["render", "--random", "--task", "pendulum", "--camera", "nope"],
         "--camera 'nope' is unknown; allowed: track, side, front, back, top"),
        (["render", str(untrained)], "has no complete checkpoint; render needs a run with one"),
    ):
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: ") and needle in err and "\n" not in err, err


def test_camera_fit_by_hand():
    # the box's bounding sphere has radius sqrt(3); the narrower half-angle is fovy/2 = 22.5 deg
    lookat, distance = camera.fit(-np.ones(3), np.ones(3), 45.0, 4 / 3)
    np.testing.assert_array_equal(lookat, np.zeros(3))
    assert distance == pytest.approx(1.1 * np.sqrt(3) / np.sin(np.radians(22.5)))
    # a tall narrow image: the horizontal half-angle atan(tan(22.5) / 2) is the narrower
    _, narrow = camera.fit(-np.ones(3), np.ones(3), 45.0, 0.5)
    half = np.arctan(np.tan(np.radians(22.5)) * 0.5)
    assert narrow == pytest.approx(1.1 * np.sqrt(3) / np.sin(half))


def _in_view(cam, points, fovy, aspect) -> bool:
    """Every point projects inside the image of MuJoCo's free camera (mjv_updateCamera)."""
    az, el = np.radians(cam.azimuth), np.radians(cam.elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    up = np.array([-np.sin(el) * np.cos(az), -np.sin(el) * np.sin(az), np.cos(el)])
    right = np.cross(forward, up)
    rel = points - (np.asarray(cam.lookat) - cam.distance * forward)
    depth = rel @ forward
    tan_v = np.tan(np.radians(fovy) / 2)
    return bool(np.all(depth > 0) and np.all(np.abs(rel @ up) / depth <= tan_v)
                and np.all(np.abs(rel @ right) / depth <= tan_v * aspect))


@pytest.mark.timeout(300)
def test_tracking_camera_keeps_robot_and_task_objects_in_frame():
    """h1hand-cube at its keyframe, and with the robot moved 1 m: every robot body, the cubes
    and the table are inside the image; a fixed view does not move between frames."""
    import mujoco

    from sirl_jax.envs import load

    _, env = load("h1hand-cube-v0")
    model = env.mj_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    track = camera.Camera(model, "track", 640, 480)
    track.start(model, data, lambda t: None, 1)
    assert track.fixtures.size  # the table
    what = track.what
    cam = track.view(model, data)
    points = np.concatenate([data.xpos[what.bodies], data.geom_xpos[track.fixtures]])
    assert len(what.bodies) > 40 and _in_view(cam, points, 45.0, 640 / 480)
    with pytest.raises(UsageError, match="allowed: track, side, front, back, top"):
        camera.Camera(model, "nope", 640, 480)
    side = camera.Camera(model, "side", 320, 240)
    side.start(model, data, lambda t: None, 10)
    first = (np.array(side.view(model, data).lookat), side.view(model, data).distance)
    data.qpos[0] += 1.0
    mujoco.mj_forward(model, data)
    assert np.array_equal(side.view(model, data).lookat, first[0])
    for _ in range(60):  # the tracking camera catches up with the moved robot
        cam = track.view(model, data)
    assert _in_view(cam, data.xpos[what.bodies], 45.0, 640 / 480)


@pytest.mark.timeout(300)
def test_render_model_is_render_only():
    """The dressed model draws the env's states (same bodies, joints, kinematics) and carries
    the look; the env's simulated model is not changed by building it, array for array."""
    import mujoco

    from sirl_jax.envs import load
    from sirl_jax.run import scene_look

    _, env = load("h1hand-bookshelf_simple-v0")
    physics = env.mj_model
    arrays = {k: np.array(getattr(physics, k)) for k in dir(physics)
              if isinstance(getattr(physics, k, None), np.ndarray)}  # fmt: skip
    model = scene_look.render_model(env)
    assert model is not physics and scene_look.same_layout(model, physics)
    for k, v in arrays.items():
        np.testing.assert_array_equal(getattr(physics, k), v, err_msg=k)
    added = np.flatnonzero(model.geom_group == scene_look.VISUAL_GROUP)
    assert len(added) == model.ngeom - physics.ngeom > 10
    assert not model.geom_contype[added].any() and not model.geom_conaffinity[added].any()
    np.testing.assert_allclose(model.body_mass, physics.body_mass)
    static = physics.body_weldid[physics.geom_bodyid] == 0
    shelves = np.flatnonzero(static & (physics.geom_group == 3))
    own = model.geom_group[model.geom_group != scene_look.VISUAL_GROUP]  # physics' geom order
    assert shelves.size and np.all(own[shelves] == 1)  # drawn by default
    assert model.ntex >= 2 and model.nmat > physics.nmat and model.nlight > physics.nlight
    data_p, data_r = mujoco.MjData(physics), mujoco.MjData(model)
    for d, m in ((data_p, physics), (data_r, model)):
        mujoco.mj_resetDataKeyframe(m, d, 0)
        d.qpos[7:] += 0.1
        mujoco.mj_kinematics(m, d)
    np.testing.assert_allclose(data_r.xpos, data_p.xpos, atol=1e-12)
    pendulum = load("pendulum")[1]
    assert scene_look.render_model(pendulum) is pendulum.mj_model  # no H1: drawn as it is


def test_goal_markers_come_from_the_task_state_of_the_named_tasks():
    from types import SimpleNamespace

    import mujoco

    from sirl_jax.run import markers

    def env(name):
        return SimpleNamespace(task=SimpleNamespace(name=name))

    np.testing.assert_array_equal(markers.goal_points(env("reach"), np.array([1.0, 2, 3])),
                                  [[1.0, 2, 3]])  # fmt: skip
    shelf = {"goals": np.arange(18.0).reshape(6, 3), "index": np.int32(2), "order": None}
    np.testing.assert_array_equal(markers.goal_points(env("bookshelf_simple"), shelf), [[6, 7, 8]])
    # window's [3] state is the head at reset, not a goal; tasks without a table entry draw none
    assert markers.goal_points(env("window"), np.zeros(3)).shape == (0, 3)
    assert markers.goal_points(SimpleNamespace(), None).shape == (0, 3)
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    scene = mujoco.MjvScene(model, maxgeom=2)
    assert markers.add_markers(scene, np.zeros((3, 3))) == 2 and scene.ngeom == 2
    np.testing.assert_allclose(scene.geoms[0].size, [markers.GOAL_RADIUS] * 3)


def test_blob_shadows_sit_under_the_bodies_turned_and_fading_with_height():
    import mujoco

    from sirl_jax.run import markers

    xml = """<mujoco><worldbody>
      <body name="pelvis" pos="0.3 -0.2 1.0" euler="0 0 90"><freejoint/>
        <geom size="0.1"/></body>
      <body name="left_ankle_link" pos="1 1 0.1"><geom size="0.05"/></body>
      <body name="right_ankle_link" pos="-1 0 0.5"><geom size="0.05"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = mujoco.MjvScene(model, maxgeom=10)
    # the right foot is 0.5 m up, past its 0.4 m fade: no disc for it
    assert markers.add_blob_shadows(scene, model, data) == 2
    pelvis, foot = scene.geoms[0], scene.geoms[1]
    np.testing.assert_allclose(pelvis.pos, [0.3, -0.2, 0.002], atol=1e-9)
    np.testing.assert_allclose(pelvis.size, [0.28, 0.22, 0.001], atol=1e-9)
    # yawed 90 degrees: the disc's long axis points along world y
    np.testing.assert_allclose(pelvis.mat.reshape(3, 3)[:, 0], [0, 1, 0], atol=1e-6)
    assert pelvis.rgba[3] == pytest.approx(0.28 * (1 - 1.0 / 2.0))
    assert foot.rgba[3] == pytest.approx(0.45 * (1 - 0.1 / 0.4))
    full = mujoco.MjvScene(model, maxgeom=1)
    assert markers.add_blob_shadows(full, model, data) == 1  # never past the scene's room
