"""Scene conventions shared by the manipulation tasks: contact bits, fixtures, free objects.

The manipulation contact profile (docs/tasks.md, "Manipulation tasks"):

- hand colliders touch the task's free objects and nothing else (not the floor, table or body);
- free objects touch the floor and the task's fixtures (table, shelves); objects touch each other
  only where a task asks (`touch_objects=True`, e.g. a peg and its block);
- the rest of the robot keeps the locomotion profile: feet, legs, body and arms vs the floor;
- no self-collision.

Bits (`humanoid.GROUP_BITS`, `BIT_OBJECT`): hands get contype 0 and conaffinity HANDS; an object
has contype HANDS (| OBJECT) and conaffinity 1 (the floor's contype) | FIXTURE (| OBJECT);
a fixture has contype FIXTURE and conaffinity 0. MuJoCo pairs two geoms when
(contype_a & conaffinity_b) | (contype_b & conaffinity_a) != 0, so no other pair exists.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from sirl_jax.envs import h1
from sirl_jax.envs.humanoid import BIT_OBJECT, GROUP_BITS

HANDS = GROUP_BITS["hands"]
OBJECT = BIT_OBJECT
FIXTURE = 1 << 8
FLOOR = h1.WORLD_CONTYPE

BOX = mujoco.mjtGeom.mjGEOM_BOX
CAPSULE = mujoco.mjtGeom.mjGEOM_CAPSULE
CYLINDER = mujoco.mjtGeom.mjGEOM_CYLINDER
SPHERE = mujoco.mjtGeom.mjGEOM_SPHERE

X_AXIS = (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0)
"""Quaternion that turns a geom's z axis onto +x (MJCF `zaxis="1 0 0"`)."""
Y_AXIS = (math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0)
"""Quaternion that turns a geom's z axis onto +y (MJCF `zaxis="0 1 0"`)."""

# HumanoidBench's task keyframes put the robot in the stand pose; some set arm joints as well.
STAND_ROBOT_QPOS = (0, 0, 0.98, 1, 0, 0, 0) + (0, 0, -0.4, 0.8, -0.4) * 2 + (0,) * 59


def use_hand_contacts(spec: mujoco.MjSpec) -> None:
    """Hand colliders (on in the "manipulation" profile) touch free objects only."""
    for name in h1.GEOM_GROUPS["hands"]:
        geom = spec.geom(name)
        geom.contype, geom.conaffinity = 0, HANDS


def add_fixture(spec: mujoco.MjSpec, parent=None, **kwargs) -> mujoco.MjsGeom:
    """A static collider that free objects rest on (table top, legs); the robot passes through."""
    parent = spec.worldbody if parent is None else parent
    kwargs.setdefault("type", BOX)
    return parent.add_geom(contype=FIXTURE, conaffinity=0, group=3, **kwargs)


def add_table(
    spec: mujoco.MjSpec,
    pos: Sequence[float],
    top: Sequence[float],
    top_z: float = 0.4,
    leg_xy: Sequence[float] | None = None,
    leg_z: float = -0.05,
    leg_half_z: float = 0.4,
) -> None:
    """HumanoidBench's table: a body at `pos` with a top box of half size `top` at z + `top_z`
    and four 0.1 x 0.1 m legs of half height `leg_half_z` at (+-x, +-y) = `leg_xy`, z `leg_z`
    (default: inset 0.1 m in x and 0.15 m in y from the top's corners, push's x +-0.4, y +-0.85
    for its 0.5 x 1 top)."""
    table = spec.worldbody.add_body(name="table", pos=pos)
    add_fixture(spec, table, name="table_top_collision", pos=(0, 0, top_z), size=top,
                rgba=(0.6, 0.45, 0.3, 1))  # fmt: skip
    lx, ly = (top[0] - 0.1, top[1] - 0.15) if leg_xy is None else leg_xy
    for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        add_fixture(spec, table, name=f"table_leg_{k + 1}_collision", pos=(sx * lx, sy * ly, leg_z),
                    size=(0.05, 0.05, leg_half_z), rgba=(0.3, 0.2, 0.1, 1))  # fmt: skip


def add_segmented_box(
    parent: mujoco.MjsBody, name: str, pos: Sequence[float], half: Sequence[float],
    segment: float, **kwargs,
) -> list[str]:
    """A static box cut along each axis into equal pieces no longer than `segment` (m), named
    `{name}_{i}{j}{k}`: the same solid, but bounding spheres MJX's broad phase can rank (a 4 m
    wall outranks every nearby pair). `kwargs` go to each piece's `add_geom` (contype, ...)."""
    counts = [max(1, math.ceil(2 * h / segment)) for h in half]
    piece = [h / n for h, n in zip(half, counts, strict=True)]
    names = []
    for idx in itertools.product(*(range(n) for n in counts)):
        centre = [p - h + (2 * c + 1) * s for p, h, c, s in zip(pos, half, idx, piece, strict=True)]
        names.append(f"{name}_{''.join(map(str, idx))}")
        kwargs.setdefault("group", 3)
        parent.add_geom(name=names[-1], type=BOX, pos=centre, size=piece, **kwargs)
    return names


def add_object_geom(
    body: mujoco.MjsBody, touch_objects: bool = False, hands: bool = True, **kwargs
) -> mujoco.MjsGeom:
    """A free object's collider: touches floor and fixtures, and the hands unless `hands` is
    False (and other objects if `touch_objects`)."""
    obj = OBJECT if touch_objects else 0
    kwargs.setdefault("group", 3)
    contype = (HANDS if hands else 0) | obj
    return body.add_geom(contype=contype, conaffinity=FLOOR | FIXTURE | obj, **kwargs)


def add_mass_geom(body: mujoco.MjsBody, density: float, **kwargs) -> mujoco.MjsGeom:
    """A non-colliding geom that carries mass (HumanoidBench's objects take their mass from the
    "visual" geoms; their "collision" geoms have mass 0)."""
    return body.add_geom(contype=0, conaffinity=0, group=1, density=density, **kwargs)


def set_inertial(
    body: mujoco.MjsBody,
    mass: float,
    inertia: Sequence[float],
    ipos: Sequence[float] = (0.0, 0.0, 0.0),
    iquat: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
) -> None:
    """An explicit inertial (HumanoidBench's `<inertial pos="0 0 0" ...>`, or the compiled
    inertial of an object whose mass comes from a mesh): mass, diagonal inertia, frame."""
    body.explicitinertial = True
    body.mass, body.inertia = mass, inertia
    body.ipos, body.iquat = ipos, iquat


def set_keyframe(
    spec: mujoco.MjSpec, robot_qpos: Sequence[float], object_qpos: Sequence[float]
) -> None:
    """Keyframe 0 = HumanoidBench's task `qpos0`: the robot's 76 entries then the objects'."""
    if len(robot_qpos) != len(STAND_ROBOT_QPOS):
        n = len(STAND_ROBOT_QPOS)
        raise ValueError(f"robot keyframe needs {n} values, got {len(robot_qpos)}")
    spec.keys[0].qpos = [float(v) for v in (*robot_qpos, *object_qpos)]


def with_robot_entries(values: dict[int, float]) -> tuple[float, ...]:
    """The stand keyframe with some robot qpos entries replaced ({qpos index: value})."""
    qpos = list(STAND_ROBOT_QPOS)
    for i, v in values.items():
        qpos[i] = v
    return tuple(qpos)


def free_joint_adr(model: mujoco.MjModel, joint: str) -> tuple[int, int]:
    """(qpos address, dof address) of a free joint."""
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if j < 0:
        raise ValueError(f"the model has no joint named {joint!r}")
    return int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])


def body_id(model: mujoco.MjModel, name: str) -> int:
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if i < 0:
        raise ValueError(f"the model has no body named {name!r}")
    return i


def hand_sites(robot, data) -> jax.Array:
    """[2, 3] the left_hand and right_hand sites."""
    return jnp.stack([robot.site_pos(data, "left_hand"), robot.site_pos(data, "right_hand")])


def euler_to_quat(angles: jax.Array) -> jax.Array:
    """[3] (roll, pitch, yaw) -> [4] (w, x, y, z), HumanoidBench's `euler_to_quat` convention."""
    c, s = jnp.cos(angles / 2), jnp.sin(angles / 2)
    cr, cp, cy = c[0], c[1], c[2]
    sr, sp, sy = s[0], s[1], s[2]
    return jnp.stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ])  # fmt: skip


def geom_ids(model: mujoco.MjModel, names: Sequence[str]) -> np.ndarray:
    ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in names])
    if (ids < 0).any():
        raise ValueError(f"unknown geoms: {[n for n, i in zip(names, ids, strict=True) if i < 0]}")
    return ids
