"""The rendered look of four tasks, the previous renderer's next to the current one (one PNG).

    .venv/bin/python -m experiments.fidelity.render_look [--out docs/results/render_look.png]

Each task is drawn at its reset keyframe (no rollout, no training). Top row: the scene model
the env simulates with the previous camera (MuJoCo's tracking camera on the pelvis, 4 m,
azimuth 135°, elevation -15°) and MuJoCo's default geom groups, as `render` drew before issue
30. Bottom row: `render`'s current defaults: the render-only model (`scene_look.render_model`),
the `track` camera and blob shadows. It draws, it times nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import tyro

TASKS = ("h1hand-walk-v0", "h1hand-cube-v0", "h1hand-bookshelf_simple-v0", "h1hand-kitchen-v0")


@dataclass(frozen=True)
class Args:
    out: str = "docs/results/render_look.png"
    width: int = 400
    height: int = 300


def _previous_camera(model):
    import mujoco

    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    cam.trackbodyid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    cam.distance, cam.elevation, cam.azimuth = 4.0, -15.0, 135.0
    return cam


def _draw(model, camera, option, width: int, height: int):
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    if camera is None:
        from sirl_jax.run.camera import Camera

        track = Camera(model, "track", width, height)
        track.start(model, data, lambda t: None, 1)
        camera = track.view(model, data)
    renderer = mujoco.Renderer(model, height, width)
    try:
        if option is None:  # the previous renderer: MuJoCo's defaults, shadow maps on
            renderer.update_scene(data, camera)
            return renderer.render()
        from sirl_jax.run.render import draw

        return draw(renderer, model, data, camera, option)
    finally:
        renderer.close()


def main(args: Args) -> None:
    from sirl_jax.run.render import select_gl

    select_gl()
    from pathlib import Path

    import numpy as np
    from PIL import Image, ImageDraw

    from sirl_jax.envs import load
    from sirl_jax.run.scene_look import render_model, scene_option

    rows = [[], []]
    for task in TASKS:
        _, env = load(task)
        rows[0].append(_draw(env.mj_model, _previous_camera(env.mj_model), None, args.width,
                             args.height))  # fmt: skip
        rows[1].append(_draw(render_model(env), None, scene_option(), args.width, args.height))
    grid = Image.fromarray(np.concatenate([np.concatenate(r, axis=1) for r in rows], axis=0))
    draw = ImageDraw.Draw(grid)
    for i, task in enumerate(TASKS):
        for j, when in enumerate(("before", "now")):
            x, y = i * args.width + 4, j * args.height + 4
            text = f"{task} ({when})"
            draw.rectangle((x - 2, y - 1, x + 6 * len(text) + 6, y + 12), fill=(0, 0, 0))
            draw.text((x, y), text, fill=(255, 255, 255))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    grid.save(args.out, optimize=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main(tyro.cli(Args))
