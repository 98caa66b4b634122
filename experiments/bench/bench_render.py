"""Rendering speed: frames/s of `render`'s drawing loop at 640x480 (OSMesa unless MUJOCO_GL).

    .venv/bin/python -m experiments.bench.bench_render [--task hurdle] [--frames 150]

Rolls out uniform random actions in MJX for `--frames` control steps (1 episode, not timed),
then times `write_video` (state copy + mj_forward + update_scene + render + caption + H.264
encode) on the same states, side by side in one run, round-robin over `--rounds`:
  previous     the renderer before the speed work: MuJoCo's shadow maps and reflections, its
               default tessellation (28 slices x 16 stacks) and 4x multisampling;
  default      `render`'s defaults now: blob shadows, `scene_look.TESSELLATION`, no MSAA;
  --antialias  the defaults with 4x multisampling;
  --shadows    the defaults with shadow maps and reflections.
and the draw alone (update_scene + render) of each. Run it on an otherwise idle machine.
"""

from __future__ import annotations

import dataclasses
import statistics
import tempfile
import time
from pathlib import Path
from unittest import mock

import tyro

from sirl_jax.run.render import select_gl

PREVIOUS_TESSELLATION = (28, 16)  # MuJoCo's default, what `render` drew with before


@dataclasses.dataclass(frozen=True)
class Args:
    task: str = "hurdle"
    frames: int = 200
    width: int = 640
    height: int = 480
    rounds: int = 3


def main(args: Args) -> None:
    backend = select_gl()  # before MuJoCo is imported
    import jax
    import mujoco
    import numpy as np

    from sirl_jax.envs import load
    from sirl_jax.run import scene_look
    from sirl_jax.run.camera import Camera
    from sirl_jax.run.render import copy_state, draw, rollout_states, write_video

    spec, env = load(args.task)

    def act(s, aux, k):
        return jax.random.uniform(k, (1, env.action_size), minval=-1.0, maxval=1.0), aux

    physics, reward, done, _ = jax.device_get(jax.jit(
        lambda k: rollout_states(env, act, None, 1, k, args.frames))(jax.random.PRNGKey(0)))
    done = np.zeros_like(done)  # draw every step, even past a fall
    qpos, qvel = np.asarray(physics.qpos), np.asarray(physics.qvel)
    # name: (tessellation, shadow maps, 4x MSAA)
    cases = {"previous": (PREVIOUS_TESSELLATION, True, True),
             "default": (scene_look.TESSELLATION, False, False),
             "--antialias": (scene_look.TESSELLATION, False, True),
             "--shadows": (scene_look.TESSELLATION, True, False)}  # fmt: skip

    def written(tessellation, shadows, antialias) -> float:
        with mock.patch.object(scene_look, "TESSELLATION", tessellation):
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                summary = write_video(env, physics, reward, done, Path(tmp) / "b.mp4", 50,
                                      args.width, args.height, spec.id, shadows,
                                      antialias=antialias)  # fmt: skip
                return summary["frames"] / (time.perf_counter() - t0)

    def drawn(tessellation, shadows, antialias) -> float:
        with mock.patch.object(scene_look, "TESSELLATION", tessellation):
            model = scene_look.render_model(env, antialias)
        data, option = mujoco.MjData(model), scene_look.scene_option()
        renderer = mujoco.Renderer(model, args.height, args.width)
        camera = Camera(model, "track", args.width, args.height)
        copy_state(model, data, qpos[0, 0], qvel[0, 0])
        camera.start(model, data, lambda t: None, 1)
        try:
            t0 = time.perf_counter()
            for t in range(args.frames):
                copy_state(model, data, qpos[t, 0], qvel[t, 0])
                draw(renderer, model, data, camera.view(model, data), option, (), shadows)
            return args.frames / (time.perf_counter() - t0)
        finally:
            renderer.close()

    rates = {(name, what): [] for name in cases for what in ("written", "drawn")}
    for _ in range(args.rounds):
        for name, case in cases.items():
            rates[(name, "written")].append(written(*case))
            rates[(name, "drawn")].append(drawn(*case))
    med = {k: statistics.median(v) for k, v in rates.items()}
    print(f"\n{spec.id}, {args.width}x{args.height}, MUJOCO_GL={backend}, {args.frames} frames, "
          f"median of {args.rounds} rounds")
    print("| renderer | tessellation | shadows | MSAA | frames/s written | frames/s drawn alone |")
    print("|---|---|---|---|---:|---:|")
    for name, (tess, shadows, antialias) in cases.items():
        print(f"| {name} | {tess[0]} x {tess[1]} | {'maps' if shadows else 'blobs'} | "
              f"{'4x' if antialias else 'off'} | {med[(name, 'written')]:.1f} | "
              f"{med[(name, 'drawn')]:.1f} |")
    ratio = statistics.median(d / p for d, p in zip(rates[("default", "written")],
                                                   rates[("previous", "written")], strict=True))
    print(f"default / previous, frames/s written (median of per-round ratios): {ratio:.2f}x")


if __name__ == "__main__":
    main(tyro.cli(Args))
