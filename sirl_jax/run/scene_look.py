"""The render-only scene: the task's model rebuilt for drawing, with a look; never simulated.

`render_model(env)` builds the task's scene again from the same code the env used (the H1's
`MjSpec` plus the task's `build`) and dresses it (`dress`): a gradient sky, a checkered floor,
HumanoidBench's headlight, a fill light, H1 colours (graphite links, silver covers), visual
housings over the fitted capsules (pelvis, chest, head and neck, thigh and shin covers, knee
caps, soles; `VISUAL_GROUP`, contype = conaffinity = 0, no mass), lighter Shadow-hand
fingers, the static fixtures (tables, shelves, the kitchen: colliders in group 3, which
MuJoCo hides) in a wood material, and the free objects that have only such colliders (push's
box, the books, the kitchen's doors) in group 1. The env's own model, the one MJX simulates,
is not touched: the render model is a second compiled model whose bodies, joints and mocap
bodies are the same (checked: `same_layout`), so a recorded qpos draws as it was simulated.

Shapes and sizes are our own, placed over our model's link frames (docs/robot.md); no
third-party mesh is used. A task without an H1 (`pendulum`) is drawn from its own model with
the floor and sky it has.
"""

from __future__ import annotations

import numpy as np

VISUAL_GROUP = 5
TESSELLATION = (16, 8)
"""Slices and stacks of the drawn spheres, capsules and cylinders (MuJoCo's default: 28, 16).
A software rasteriser's draw is bound by triangles: 16 x 8 draws h1hand-walk 1.4x faster at
640x480 (experiments/bench/bench_render.py), and its capsules still read as round."""
MSAA_SAMPLES = 4
"""Multisampling of `render --antialias`. Off by default: on a software rasteriser (OSMesa) 4x
MSAA costs 2.3x the draw of h1hand-hurdle at 640x480; on a GPU it is free."""
"""The geom group of the render-only housings (MuJoCo draws groups 0-2 by default)."""
HIDDEN_GROUP = 4
FIXTURE_GROUP = 1

_GRAPHITE, _SILVER, _FACE = (0.11, 0.11, 0.12, 1), (0.62, 0.64, 0.67, 1), (0.02, 0.02, 0.03, 1)
_RUBBER, _HAND = (0.2, 0.2, 0.2, 1), (0.30, 0.31, 0.33, 1)
_OBJECT = (0.85, 0.35, 0.2, 1)

# (body, geom type, size, pos, material): housings in the body's frame (metres). The frames
# are our model's (assets/h1_shadow/h1_shadow.xml); the sizes follow its fitted capsules.
_HOUSINGS = [
    ("pelvis", "box", (0.075, 0.115, 0.055), (0.0, 0.0, -0.035), "h1_graphite"),
    ("torso_link", "box", (0.085, 0.13, 0.115), (0.0, 0.0, 0.36), "h1_graphite"),
    ("torso_link", "box", (0.065, 0.095, 0.1), (0.0, 0.0, 0.15), "h1_graphite"),
    ("torso_link", "cylinder", (0.035, 0.04), (0.02, 0.0, 0.52), "h1_graphite"),
    ("torso_link", "ellipsoid", (0.085, 0.075, 0.095), (0.035, 0.0, 0.64), "h1_silver"),
    ("torso_link", "box", (0.012, 0.05, 0.032), (0.108, 0.0, 0.65), "h1_face"),
]
_LEG = [
    ("hip_pitch_link", "box", (0.055, 0.05, 0.15), (0.01, 0.0, -0.19), "h1_silver"),
    ("hip_pitch_link", "cylinder", (0.065, 0.045), (0.0, 0.0, 0.0), "h1_graphite"),
    ("knee_link", "sphere", (0.055,), (0.0, 0.0, 0.0), "h1_graphite"),
    ("knee_link", "box", (0.042, 0.04, 0.15), (0.006, 0.0, -0.19), "h1_silver"),
    ("ankle_link", "box", (0.115, 0.042, 0.012), (0.055, 0.0, -0.068), "h1_rubber"),
]
_HIDE = ("shoulders",)
"""Fitted capsules the housings replace in the picture (the big chest-and-head pill)."""


def _materials(spec) -> None:
    import mujoco

    sky = spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                           builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=256, height=256)
    sky.rgb1, sky.rgb2 = (0.55, 0.72, 0.9), (0.95, 0.96, 0.98)
    grid = spec.add_texture(name="floor_grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                            builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                            mark=mujoco.mjtMark.mjMARK_EDGE)  # fmt: skip
    grid.rgb1, grid.rgb2, grid.markrgb = (0.52, 0.56, 0.6), (0.44, 0.48, 0.52), (0.7, 0.72, 0.75)
    floor = spec.add_material(name="floor", texrepeat=(8, 8), reflectance=0.0, specular=0.2)
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "floor_grid"
    for name, rgba, specular in (("h1_graphite", _GRAPHITE, 0.5), ("h1_silver", _SILVER, 0.6),
                                 ("h1_face", _FACE, 0.9), ("h1_rubber", _RUBBER, 0.1),
                                 ("h1_hand", _HAND, 0.4),
                                 ("fixture", (0.62, 0.45, 0.3, 1), 0.15)):  # fmt: skip
        spec.add_material(name=name, rgba=rgba, specular=specular, shininess=0.3)


def _lights(spec) -> None:
    head = spec.visual.headlight
    head.diffuse, head.ambient, head.specular = (0.6, 0.6, 0.6), (0.3, 0.3, 0.3), (0, 0, 0)
    fill = spec.worldbody.add_light(name="fill", pos=(-2.0, 2.0, 3.0), dir=(0.5, -0.5, -0.7))
    fill.castshadow, fill.diffuse = False, (0.25, 0.25, 0.25)


def _housings(spec, names: set[str]) -> None:
    import mujoco

    kinds = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
             "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
             "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID}  # fmt: skip
    shapes = list(_HOUSINGS)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        for link, kind, size, (x, y, z), mat in _LEG:
            quat = (0.7071068, 0.7071068, 0.0, 0.0) if kind == "cylinder" else (1.0, 0, 0, 0)
            shapes.append((f"{side}_{link}", kind, size, (x, sign * y, z), mat, quat))
    for shape in shapes:
        body, kind, size, pos, mat = shape[:5]
        if body not in names:
            continue
        size3 = tuple(size) + (0.0,) * (3 - len(size))
        spec.body(body).add_geom(type=kinds[kind], size=size3, pos=pos,
                                 quat=shape[5] if len(shape) > 5 else (1.0, 0, 0, 0),
                                 material=mat, contype=0, conaffinity=0, group=VISUAL_GROUP,
                                 density=0.0, mass=0.0)  # fmt: skip


def dress(spec, model) -> None:
    """Adds the look to `spec` (uncompiled; `model` is its plain compilation, for the static
    geoms). Geoms are matched by index: `spec.geoms` lists them in compile order."""
    import mujoco

    _materials(spec)
    _lights(spec)
    geoms = list(spec.geoms)
    welded = model.body_weldid[model.geom_bodyid] == 0
    for i, geom in enumerate(geoms):
        if geom.name == "floor":
            geom.material, geom.rgba = "floor", (1, 1, 1, 1)
        elif geom.name in _HIDE:
            geom.group = HIDDEN_GROUP
        elif welded[i] and model.geom_type[i] != mujoco.mjtGeom.mjGEOM_PLANE:
            if model.geom_group[i] == 3:
                geom.group = FIXTURE_GROUP
                geom.material = "fixture"
                if np.allclose(model.geom_rgba[i], (0.5, 0.5, 0.5, 1)):
                    geom.rgba = (0.62, 0.45, 0.3, 1)
        elif geom.name.startswith(("lh_", "rh_")) and model.geom_group[i] == 2:
            geom.material, geom.rgba = "h1_hand", _HAND
        elif model.geom_group[i] == 2 and model.geom_contype[i] | model.geom_conaffinity[i]:
            geom.material, geom.rgba = "h1_graphite", _GRAPHITE
    for i in _unseen_object_geoms(model):
        geoms[i].group = FIXTURE_GROUP
        if np.allclose(model.geom_rgba[i], (0.5, 0.5, 0.5, 1)):
            geoms[i].rgba = _OBJECT
    names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)}
    _housings(spec, names)


def _unseen_object_geoms(model) -> np.ndarray:
    """Geoms of moving task bodies (not the robot) that have no geom in a drawn group (0-2):
    their colliders (group 3, hidden by MuJoCo) are all there is to show (push's box)."""
    import mujoco

    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    out = []
    for body in range(1, model.nbody):
        if model.body_rootid[body] == model.body_rootid[pelvis] or not model.body_jntnum[body]:
            continue
        own = np.flatnonzero(model.geom_bodyid == body)
        if own.size and np.all(model.geom_group[own] >= 3):
            out += own.tolist()
    return np.array(out, int)


def same_layout(a, b) -> bool:
    """Whether a state of model `a` draws in model `b`: the same bodies, joints, qpos/qvel and
    mocap bodies, in the same order."""
    fields = ("nq", "nv", "nbody", "njnt", "nmocap")
    return (all(getattr(a, f) == getattr(b, f) for f in fields)
            and np.array_equal(a.jnt_qposadr, b.jnt_qposadr)
            and np.array_equal(a.body_parentid, b.body_parentid))  # fmt: skip


def render_model(env, antialias: bool = False):
    """The model to draw `env` with: the dressed rebuild of its scene (multisampled with
    `antialias`), or its own model when the env is not an H1 task (or the rebuild does not
    match it)."""
    from sirl_jax.envs import h1

    task, variant = getattr(env, "task", None), getattr(env, "variant", None)
    if task is None or variant not in h1.VARIANTS:
        return env.mj_model
    def build():
        spec = h1.robot_spec(variant=variant, contacts=task.contacts)
        task.build(spec, variant)
        return spec

    plain = build().compile()
    spec = build()
    if plain.ngeom != len(list(spec.geoms)) or not same_layout(plain, env.mj_model):
        return env.mj_model
    dress(spec, plain)
    model = spec.compile()
    if not same_layout(model, env.mj_model):
        return env.mj_model
    model.vis.quality.numslices, model.vis.quality.numstacks = TESSELLATION
    model.vis.quality.offsamples = MSAA_SAMPLES if antialias else 0
    return model


def scene_option():
    """The groups to draw: MuJoCo's 0-2 (robot, objects, fixtures moved to 1) and the housings."""
    import mujoco

    option = mujoco.MjvOption()
    option.geomgroup[:] = 0
    for group in (0, 1, 2, VISUAL_GROUP):
        option.geomgroup[group] = 1
    return option


__all__ = [
    "MSAA_SAMPLES", "TESSELLATION", "VISUAL_GROUP", "dress", "render_model", "same_layout",
    "scene_option",
]
