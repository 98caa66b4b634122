"""`render`: an mp4 of a policy, rolled out in MJX and drawn by CPU MuJoCo.

The rollout (planner, policy prior, or uniform random actions) runs as one jitted `lax.scan`
over N parallel episodes and returns the physics state of every step. Each state's qpos and
qvel are copied into a `mujoco.MjData` of a render-only rebuild of the env's scene
(`scene_look.render_model`: the same bodies and joints as `Env.mj_model`, obstacles included,
plus visual housings, sky, floor and materials; the simulated model is never changed),
forwarded, and drawn by `mujoco.Renderer` from `--camera` (`camera.py`; by default one that
tracks the robot and the task's objects). Frames go to imageio's ffmpeg writer at the control
rate (50 fps for the H1 tasks), episode after episode, with the step and the return so far
drawn on each.

Headless OpenGL is chosen before MuJoCo is imported (`select_gl`): EGL where an NVIDIA GPU is
visible, OSMesa otherwise, unless MUJOCO_GL is set. A missing library is a one-line error naming
the system package.
"""

from __future__ import annotations

import ctypes.util
import os
import warnings
from pathlib import Path
from typing import Any

from sirl_jax.run.camera import Camera, check_camera
from sirl_jax.run.errors import UsageError
from sirl_jax.run.markers import add_blob_shadows, add_markers, goal_points
from sirl_jax.run.scene_look import render_model, scene_option

_GL_LIBS = {
    "osmesa": ("OSMesa", "libosmesa6"),
    "egl": ("EGL", "libegl1 (with libgl1-mesa-dri, or the NVIDIA driver's EGL)"),
}


def select_gl(environ: dict | None = None) -> str:
    """Sets MUJOCO_GL and PYOPENGL_PLATFORM for headless rendering; returns the backend.

    Must run before `mujoco` is first imported (MuJoCo reads MUJOCO_GL at import). A value the
    user set is kept. Raises UsageError when the backend's library is not installed.
    """
    env = os.environ if environ is None else environ
    backend = env.get("MUJOCO_GL") or ("egl" if os.path.exists("/dev/nvidia0") else "osmesa")
    if backend in _GL_LIBS:
        lib, package = _GL_LIBS[backend]
        if ctypes.util.find_library(lib) is None:
            raise UsageError(
                f"headless rendering with MUJOCO_GL={backend} needs lib{lib}, which is not "
                f"installed: install the system package {package} (Debian/Ubuntu: apt-get "
                f"install {package.split()[0]}), or set MUJOCO_GL to a backend you have"
            )
    env.setdefault("MUJOCO_GL", backend)
    env.setdefault("PYOPENGL_PLATFORM", backend)
    return backend


def rollout_states(env, act, aux0, num_episodes: int, key, steps: int):
    """Runs N episodes for `steps` control steps under `act(env_state, aux, key)`.

    Returns (physics [steps, N, ...] of the state each step starts from, reward [steps, N],
    done [steps, N], task state [steps, N, ...] of the same states) as device arrays; jit it.
    """
    import jax

    from sirl_jax.envs.base import VecEnv

    vec = VecEnv(env, num_episodes)
    key_reset, key_run = jax.random.split(key)

    def body(carry, k):
        state, aux = carry
        action, aux = act(state, aux, k)
        nxt = vec.step(state, action)
        return (nxt, aux), (env.mjx_data(state.physics), nxt.reward,
                            nxt.terminated | nxt.truncated, state.task)  # fmt: skip

    _, out = jax.lax.scan(body, (vec.reset(key_reset), aux0), jax.random.split(key_run, steps))
    return out


def copy_state(model, data, qpos, qvel, mocap_pos=None, mocap_quat=None) -> None:
    """Writes one MJX state into a CPU `MjData` and runs `mj_forward` (positions for drawing)."""
    import mujoco

    data.qpos[:] = qpos
    data.qvel[:] = qvel
    if mocap_pos is not None and model.nmocap:
        data.mocap_pos[:] = mocap_pos
        data.mocap_quat[:] = mocap_quat
    mujoco.mj_forward(model, data)


def _caption(frame, text: str):
    from PIL import Image, ImageDraw

    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    draw.rectangle((0, 0, 8 + 7 * len(text), 18), fill=(0, 0, 0))
    draw.text((4, 3), text, fill=(255, 255, 255))
    return image


def draw(renderer, model, data, camera, option, goals=(), shadows: bool = False):
    """One frame of `data` (forwarded) from `camera`: the scene, the goal markers, and either
    MuJoCo's shadow maps and reflections or blob shadows (`markers.add_blob_shadows`)."""
    import mujoco

    renderer.update_scene(data, camera, option)
    add_markers(renderer.scene, goals)
    if not shadows:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        add_blob_shadows(renderer.scene, model, data)
    return renderer.render()


def write_video(env, physics, reward, done, out: Path, fps: int, width: int, height: int,
                title: str, shadows: bool = False, camera: str = "track",
                task_state: Any = None, antialias: bool = False) -> dict[str, Any]:  # fmt: skip
    """Draws every episode's frames (up to its first end) into `out`; returns a summary.

    camera: `camera.VIEWS` or one of the model's cameras (`camera.Camera`). task_state: the
    task state of every step (leaves [steps, N, ...]); its goals are drawn (`markers.py`).

    shadows: MuJoCo's shadow maps and floor reflections, about 2.5x slower on a software
    rasteriser (OSMesa); without them (the default) blob shadows ground the robot
    (`markers.add_blob_shadows`). antialias: 4x MSAA (`scene_look.MSAA_SAMPLES`), about 2.3x
    slower without a GPU. Frames/s of each: experiments/bench/bench_render.py.
    """
    import imageio.v2 as imageio
    import jax
    import mujoco
    import numpy as np

    model = render_model(env, antialias)
    option = scene_option()
    data = mujoco.MjData(model)
    qpos, qvel = np.asarray(physics.qpos), np.asarray(physics.qvel)
    mocap = None
    if model.nmocap:
        mocap = (np.asarray(physics.mocap_pos), np.asarray(physics.mocap_quat))
    reward, done = np.asarray(reward), np.asarray(done)
    steps, episodes = reward.shape
    view = Camera(model, camera, width, height)
    renderer = mujoco.Renderer(model, height, width)
    out.parent.mkdir(parents=True, exist_ok=True)
    frames, returns = 0, []
    # imageio starts ffmpeg with fork+exec; JAX warns about any fork, harmlessly here.
    warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
    try:
        # x264's veryfast preset: about 2x the encoding rate of its default at the same size
        with imageio.get_writer(out, fps=fps, codec="libx264", quality=7, macro_block_size=1,
                                ffmpeg_params=["-preset", "veryfast"]) as writer:  # fmt: skip
            for ep in range(episodes):
                ended = np.flatnonzero(done[:, ep])
                length = int(ended[0]) + 1 if ended.size else steps
                total = 0.0

                def pose(t, ep=ep):
                    data.qpos[:] = qpos[t, ep]
                    if mocap:
                        data.mocap_pos[:], data.mocap_quat[:] = mocap[0][t, ep], mocap[1][t, ep]
                    mujoco.mj_kinematics(model, data)

                view.start(model, data, pose, length)
                for t in range(length):
                    extra = (mocap[0][t, ep], mocap[1][t, ep]) if mocap else ()
                    copy_state(model, data, qpos[t, ep], qvel[t, ep], *extra)
                    goals = goal_points(env, None if task_state is None else jax.tree.map(
                        lambda x, t=t, ep=ep: x[t, ep], task_state))  # fmt: skip
                    frame = draw(renderer, model, data, view.view(model, data, goals), option,
                                 goals, shadows)  # fmt: skip
                    text = (f"{title}  episode {ep + 1}/{episodes}  step {t}  "
                            f"return {total:.1f}")  # fmt: skip
                    writer.append_data(np.asarray(_caption(frame, text)))
                    total += float(reward[t, ep])
                    frames += 1
                returns.append(total)
    finally:
        renderer.close()
    return {"frames": frames, "returns": returns, "out": str(out)}


def _check_scene(spec, env, camera: str) -> None:
    """Before any rollout: the task has a MuJoCo scene, and `camera` is one of its cameras."""
    if env.mj_model is None:
        raise UsageError(f"task {spec.id} has no MuJoCo model to render")
    check_camera(camera, env.mj_model)


def render_command(args, backend: str) -> None:
    """`render` from parsed `cli.RenderArgs` (after `select_gl`); prints what it wrote."""
    from sirl_jax.run.compile_cache import enable_compilation_cache

    enable_compilation_cache()
    summary = render(
        Path(args.run) if args.run else None, task=args.task, step=args.step,
        episodes=args.episodes, policy="random" if args.random else args.policy,
        out=Path(args.out) if args.out else None, max_steps=args.max_steps, width=args.width,
        height=args.height, shadows=args.shadows, camera=args.camera,
        antialias=args.antialias)  # fmt: skip
    returns = ", ".join(f"{r:.1f}" for r in summary["returns"])
    print(f"wrote {summary['out']}: {summary['frames']} frames ({args.width}x{args.height}, "
          f"MUJOCO_GL={backend}), episode returns {returns}")  # fmt: skip


def render(run_dir: Path | None, *, task: str | None, step: int | None, episodes: int,
           policy: str, out: Path | None, max_steps: int | None, width: int, height: int,
           shadows: bool = False, seed: int = 0, camera: str = "track",
           antialias: bool = False) -> dict[str, Any]:  # fmt: skip
    """The body of `render` (call `select_gl` first). A run's video goes to
    RUN_DIR/videos/<step>-<policy>.mp4 by default, where `report` finds it."""
    import jax

    from sirl_jax.run import runlog
    from sirl_jax.run.checkpoint import Checkpointer
    from sirl_jax.run.checkpoint_files import complete_steps
    from sirl_jax.run.runner import build, eval_key, load_task
    from sirl_jax.run.states import restore_state

    if policy not in ("planner", "prior", "random"):
        raise UsageError(f"--policy {policy!r} is invalid; allowed: planner, prior (or --random)")
    if episodes < 1:
        raise UsageError(f"--episodes={episodes} is invalid; allowed: an int >= 1")
    if run_dir is None:
        if policy != "random" or task is None:
            raise UsageError("give a RUN_DIR, or --random with --task NAME")
        spec, env = load_task(task)
        _check_scene(spec, env, camera)
        agent, agent_state = None, None
    else:
        if not run_dir.is_dir():
            raise UsageError(f"run directory {run_dir} does not exist")
        config = runlog.load_config(run_dir)
        spec, train = build(config)
        env, agent = train.env, train.agent
        _check_scene(spec, env, camera)
        if not complete_steps(run_dir / "checkpoints"):
            raise UsageError(f"{run_dir} has no complete checkpoint; render needs a run with "
                             "one, or --random --task NAME (no run)")  # fmt: skip
        ckpt = Checkpointer(run_dir / "checkpoints")
        try:
            state, step = restore_state(ckpt, train.init, jax.random.PRNGKey(config.train.seed),
                                        step)  # fmt: skip
        finally:
            ckpt.close()
        agent_state, seed = state.agent, config.train.seed
    if out is None:
        out = (Path(f"{spec.id}-{policy}.mp4") if run_dir is None
               else run_dir / "videos" / f"{step}-{policy}.mp4")  # fmt: skip
    return render_policy(env, agent, agent_state, policy, episodes, eval_key(seed, step or 0),
                         out, f"{spec.id} {policy}", max_steps=max_steps, width=width,
                         height=height, shadows=shadows, camera=camera,
                         antialias=antialias)  # fmt: skip


def render_policy(env, agent, agent_state, policy: str, episodes: int, key, out: Path,
                  title: str, *, max_steps: int | None = None, width: int = 640,
                  height: int = 480, shadows: bool = False, camera: str = "track",
                  antialias: bool = False) -> dict[str, Any]:  # fmt: skip
    """Rolls out `policy` (planner or prior in eval mode, or random; `agent_state` of one
    seed) for `episodes` episodes of at most `max_steps` steps and writes their mp4 to `out`
    (call `select_gl` first); returns `write_video`'s summary."""
    import jax

    steps = min(env.episode_length, max_steps or env.episode_length)
    if policy == "random":
        def act(s, aux, k):
            return jax.random.uniform(k, (episodes, env.action_size), minval=-1.0,
                                      maxval=1.0), aux  # fmt: skip
        aux0 = None
    elif policy == "planner":
        def act(s, aux, k):
            return agent.plan(agent_state, aux, s.obs, s.first, k, True)
        aux0 = agent.init_planner(episodes)
    else:
        def act(s, aux, k):
            return agent.act_policy(agent_state, s.obs, k, True), aux
        aux0 = None
    physics, reward, done, task_state = jax.device_get(jax.jit(
        lambda k: rollout_states(env, act, aux0, episodes, k, steps))(key))  # fmt: skip
    fps = max(1, round(1.0 / env.control_dt))
    return write_video(env, physics, reward, done, out, fps, width, height, title, shadows,
                       camera, task_state, antialias)
