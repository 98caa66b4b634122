"""Rendering speed: frames/s of `render`'s drawing loop at 640x480 (OSMesa unless MUJOCO_GL).

    .venv/bin/python -m experiments.bench.bench_render [--task hurdle] [--frames 200]

Rolls out uniform random actions in MJX for `--frames` control steps (1 episode, not timed),
then times `write_video` (state copy + mj_forward + update_scene + render + caption + H.264
encode) with and without shadows, and the MuJoCo draw alone (update_scene + render, shadows
on) on the same states.
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
from pathlib import Path

import tyro

from sirl_jax.run.render import select_gl


@dataclasses.dataclass(frozen=True)
class Args:
    task: str = "hurdle"
    frames: int = 200
    width: int = 640
    height: int = 480


def main(args: Args) -> None:
    backend = select_gl()  # before MuJoCo is imported
    import jax
    import mujoco
    import numpy as np

    from sirl_jax.envs import load
    from sirl_jax.run.camera import Camera
    from sirl_jax.run.render import copy_state, rollout_states, write_video

    spec, env = load(args.task)

    def act(s, aux, k):
        return jax.random.uniform(k, (1, env.action_size), minval=-1.0, maxval=1.0), aux

    physics, reward, done, _ = jax.device_get(jax.jit(
        lambda k: rollout_states(env, act, None, 1, k, args.frames))(jax.random.PRNGKey(0)))
    done = np.zeros_like(done)  # draw every step, even past a fall
    written = {}
    for shadows in (True, False):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            summary = write_video(env, physics, reward, done, Path(tmp) / "b.mp4", 50,
                                  args.width, args.height, spec.id, shadows)  # fmt: skip
            written[shadows] = summary["frames"] / (time.perf_counter() - t0)
    model, data = env.mj_model, mujoco.MjData(env.mj_model)
    renderer = mujoco.Renderer(model, args.height, args.width)
    camera = Camera(model, "track", args.width, args.height)
    qpos, qvel = np.asarray(physics.qpos), np.asarray(physics.qvel)
    copy_state(model, data, qpos[0, 0], qvel[0, 0])
    camera.start(model, data, lambda t: None, 1)
    t0 = time.perf_counter()
    for t in range(args.frames):
        copy_state(model, data, qpos[t, 0], qvel[t, 0])
        renderer.update_scene(data, camera.view(model, data))
        renderer.render()
    draw = args.frames / (time.perf_counter() - t0)
    renderer.close()
    print(f"{spec.id} {args.width}x{args.height} MUJOCO_GL={backend}: {written[True]:.1f} "
          f"frames/s written (draw + caption + encode; --no-shadows: {written[False]:.1f}), "
          f"{draw:.1f} frames/s drawn alone")


if __name__ == "__main__":
    main(tyro.cli(Args))
