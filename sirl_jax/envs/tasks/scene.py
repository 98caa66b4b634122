"""The task scenes' shared vocabulary: contact bits, static and free colliders, props.

Contact bits. The robot module gives robot colliders contype=2 conaffinity=1 and the floor
contype=1 conaffinity=2 (robot-floor only; no self-collision). MuJoCo pairs two geoms when
(contype_a & conaffinity_b) | (contype_b & conaffinity_a) != 0, so a scene geom touches exactly
what its bits name:

- `GROUP_BITS`: a task that wants a scene geom to touch only some robot parts adds the bit of
  each such group to those parts' conaffinity (`set_contact_bits`) and gives the scene geom the
  bits as contype and conaffinity 0 (`add_static_geom`), so static scene geoms never touch each
  other. "links" (the fitted capsules of docs/robot.md) touch nothing but such geoms: the
  obstacles, stair's and slide's steps, and in the `hb` contact set the fixtures and objects
  (`use_link_contacts`).
- `HANDS`, `OBJECT`, `FIXTURE`, `FLOOR`: the manipulation profile (docs/tasks.md, "Manipulation
  tasks"). Hand colliders touch the task's free objects and nothing else (`use_hand_contacts`:
  contype 0, conaffinity HANDS); a free object has contype HANDS (| OBJECT) and conaffinity
  FLOOR | FIXTURE (| OBJECT) (`add_object_geom`), so objects touch each other only where a task
  asks; a fixture has contype FIXTURE and conaffinity 0 (`add_fixture`); the rest of the robot
  keeps the locomotion profile (feet, legs, body and arms against the floor).

Props. MJX has no cylinder-box pair (and refuses a model that has one), while palms, shelves
and tables are boxes, so HumanoidBench's cylinders become: flat discs and ear cups a box of the
disc's area and thickness, long rods a capsule of the same length, a standing can a box of the
same area. Mass and inertia always come from HumanoidBench's own shapes (non-colliding geoms at
density 1000, its "visual" geoms' default), so every object weighs what it does there.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence

import mujoco

from sirl_jax.envs import h1

GROUP_BITS = {
    "feet": 1 << 2, "legs": 1 << 3, "body": 1 << 4, "arms": 1 << 5, "hands": 1 << 6,
    "links": 1 << 9,
}  # fmt: skip
OBJECT = 1 << 7
"""Free task objects that touch each other (balance board and pivot, cubes, pegs) share it."""

HANDS = GROUP_BITS["hands"]
"""Hand colliders' conaffinity in the manipulation profile: they touch free objects only."""
FIXTURE = 1 << 8
"""Static colliders that free objects rest on (tables, shelves); the robot passes through."""
FLOOR = h1.WORLD_CONTYPE
LINKS = GROUP_BITS["links"]
"""The fitted link capsules' bit (hip yaw/roll, shoulder pitch/roll, ankle and shoulder
housings): on in the `hb` contact set against fixtures and objects, never against the floor."""

BOX = mujoco.mjtGeom.mjGEOM_BOX
CAPSULE = mujoco.mjtGeom.mjGEOM_CAPSULE
CYLINDER = mujoco.mjtGeom.mjGEOM_CYLINDER
SPHERE = mujoco.mjtGeom.mjGEOM_SPHERE

X_AXIS = (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0)
"""Quaternion that turns a geom's z axis onto +x (MJCF `zaxis="1 0 0"`)."""
Y_AXIS = (math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0)
"""Quaternion that turns a geom's z axis onto +y (MJCF `zaxis="0 1 0"`)."""


@functools.cache
def robot_groups(variant: str) -> dict[str, tuple[str, ...]]:
    """Robot collider names by group ("feet", "legs", "body", "arms"[, "hands"]) of a variant."""
    return dict(h1.Robot(h1.load_model(variant)).geom_groups)


def set_contact_bits(
    spec: mujoco.MjSpec, groups: dict[str, tuple[str, ...]], names: tuple[str, ...]
) -> int:
    """Adds the bit of each robot group in `names` to its geoms' conaffinity.

    Returns the OR of those bits: the contype a scene geom needs to touch exactly those groups.
    """
    bits = 0
    for name in names:
        if name not in GROUP_BITS:
            raise ValueError(f"unknown robot geom group {name!r}; allowed: {sorted(GROUP_BITS)}")
        for geom_name in groups.get(name, ()):
            geom = spec.geom(geom_name)
            if geom is None:
                raise ValueError(f"robot geom {geom_name!r} of group {name!r} not in the spec")
            geom.conaffinity = int(geom.conaffinity) | GROUP_BITS[name]
        bits |= GROUP_BITS[name]
    return bits


def set_max_geom_pairs(spec: mujoco.MjSpec, k: int) -> None:
    """MJX broad phase: per collision-function group keep only the k candidate pairs whose
    bounding spheres are closest (plane groups are never pruned). Scenes with many static geoms
    (maze blocks, poles, stairs) use it so the per-step contact work stays that of a few pairs."""
    if k < 1:
        raise ValueError(f"max_geom_pairs must be >= 1, got {k}")
    spec.add_numeric(name="max_geom_pairs", data=[float(k)])


def add_static_geom(
    spec: mujoco.MjSpec,
    contype: int,
    gtype: mujoco.mjtGeom = mujoco.mjtGeom.mjGEOM_BOX,
    **kwargs,
) -> mujoco.MjsGeom:
    """A world geom that touches the robot parts whose bits are in `contype` and nothing else."""
    geom = spec.worldbody.add_geom(type=gtype, contype=contype, conaffinity=0, **kwargs)
    return geom


def use_hand_contacts(spec: mujoco.MjSpec) -> None:
    """Hand colliders (on in the "manipulation" profile) touch free objects only."""
    for name in h1.GEOM_GROUPS["hands"]:
        geom = spec.geom(name)
        geom.contype, geom.conaffinity = 0, HANDS


PRISM_SIDES = 16
"""Sides of the prism that stands in for a colliding cylinder in the `hb` contact set."""
PRISM_TAG = "_prism_"
"""Part of the name of every mesh `cylinder_to_prism` makes (`prism_meshes`)."""


def use_link_contacts(spec: mujoco.MjSpec) -> None:
    """The link capsules (`h1.GEOM_GROUPS["links"]`) touch scene geoms whose contype has
    LINKS. HumanoidBench's hip, shoulder and ankle housings and its torso's shoulders are
    colliders like any other: against a table or a counter they are what touches first."""
    set_contact_bits(spec, {"links": h1.GEOM_GROUPS["links"]}, ("links",))


def use_hb_contacts(spec: mujoco.MjSpec, prism_sides: int = PRISM_SIDES) -> None:
    """HumanoidBench's contact set (`contact_set="hb"`, sirl_jax/hb_compat.py): every fixture
    touches the robot's colliders and hands, every free object touches the robot's colliders,
    the hands and the other objects. Call it once the scene is built.

    Fixtures (contype FIXTURE, conaffinity 0) gain FLOOR | HANDS | LINKS in contype: the
    robot's colliders have conaffinity FLOOR, the hands HANDS, the link capsules LINKS
    (`use_link_contacts`); fixtures still never touch each other or the floor. Objects
    (conaffinity FIXTURE) gain HANDS | OBJECT | LINKS in contype and OBJECT | ROBOT_CONTYPE in
    conaffinity. Door's panel and walls carry their own bits and leave LINKS out (docs/tasks.md:
    MJX's cull then drops more touching pairs, and MuJoCo C's agreement gains nothing). MJX has
    no box-cylinder pair, and the robot's soles and palms are boxes, so every colliding cylinder
    becomes a `prism_sides`-gon prism of the same area and length (`cylinder_to_prism`)."""
    use_link_contacts(spec)
    for geom in spec.geoms:
        if geom.contype & FIXTURE and geom.conaffinity == 0:
            geom.contype |= FLOOR | HANDS | LINKS
        elif geom.conaffinity & FIXTURE:
            geom.contype |= HANDS | OBJECT | LINKS
            geom.conaffinity |= OBJECT | h1.ROBOT_CONTYPE
    for geom in list(spec.geoms):
        if geom.type == CYLINDER and (geom.contype or geom.conaffinity):
            cylinder_to_prism(spec, geom, prism_sides)


def prism_radius(radius: float, sides: int) -> float:
    """Circumradius of the regular `sides`-gon whose area is that of a circle of `radius`: its
    vertices lie 1.3% outside the circle and its edge midpoints 0.65% inside (16 sides)."""
    return radius * math.sqrt(2 * math.pi / (sides * math.sin(2 * math.pi / sides)))


def prism_meshes(model: mujoco.MjModel) -> list[int]:
    """Ids of the meshes `cylinder_to_prism` made in a compiled model."""
    return [i for i in range(model.nmesh) if PRISM_TAG in model.mesh(i).name]


def cylinder_to_prism(spec: mujoco.MjSpec, geom: mujoco.MjsGeom, sides: int) -> None:
    """Turns a cylinder geom into a convex mesh prism along its z axis: same frame, length and
    cross-section area (`prism_radius`). MJX collides meshes with boxes (`convex_convex`)."""
    radius, half = float(geom.size[0]), float(geom.size[1])
    r = prism_radius(radius, sides)
    verts = []
    for z in (-half, half):
        for k in range(sides):
            a = 2 * math.pi * k / sides
            verts += [r * math.cos(a), r * math.sin(a), z]
    mesh = spec.add_mesh(name=f"{geom.name or 'cylinder'}{PRISM_TAG}{len(spec.meshes)}")
    mesh.uservert = verts
    geom.type = mujoco.mjtGeom.mjGEOM_MESH
    geom.meshname = mesh.name


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
    segment: float, along: str = "all", group: int = 3, **kwargs,
) -> list[str]:
    """A static box of half size `half` cut into equal pieces no longer than `segment` (m): the
    same solid, but bounding spheres MJX's broad phase can rank (a 4 m wall outranks every
    nearby pair). Returns the pieces' names.

    along: "all" cuts every axis (pieces `{name}_{i}{j}{k}`); "longest" only the longest one
      (pieces `{name}_{i}`). group: the geom group (3, collision-only, for fixtures and walls
      drawn by other geoms; 0 for obstacles that are their own visuals). `kwargs` go to each
      piece's `add_geom` (contype, conaffinity, rgba).
    """
    if along not in ("all", "longest"):
        raise ValueError(f"along={along!r} is invalid; allowed: 'all', 'longest'")
    longest = max(range(3), key=lambda a: half[a])
    cut = range(3) if along == "all" else (longest,)
    counts = [max(1, math.ceil(2 * h / segment)) if a in cut else 1 for a, h in enumerate(half)]
    piece = [h / n for h, n in zip(half, counts, strict=True)]
    names = []
    for idx in itertools.product(*(range(n) for n in counts)):
        # Equal in exact arithmetic; each mode keeps the rounding its tasks were compiled with
        # (obstacles from the centre, fixtures and walls from the corner), so models are
        # unchanged bit for bit.
        centre = [(p + (-h + (2 * c + 1) * s) if along == "longest" else p - h + (2 * c + 1) * s)
                  if a in cut else p
                  for a, (p, h, c, s) in enumerate(zip(pos, half, idx, piece, strict=True))]
        suffix = "".join(map(str, idx)) if along == "all" else str(idx[longest])
        names.append(f"{name}_{suffix}")
        parent.add_geom(name=names[-1], type=BOX, pos=centre, size=piece, group=group, **kwargs)
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



# -- Props: furniture and household objects (room, bookshelf) --------------------

DENSITY = 1000.0
WOOD = (0.55, 0.4, 0.28, 1)


SHELF_PANEL_SEGMENT = 0.6
"""Longest piece (m) of the shelf's top, sides and back panel (`add_shelf`)."""


def add_shelf(spec: mujoco.MjSpec, pos: Sequence[float]) -> mujoco.MjsBody:
    """HumanoidBench's shelf (static fixture): six 0.6 x 0.8 m boards 0.3 m apart from z 0,
    a top board, two sides and a back panel at +x.

    The top, sides and back are cut into pieces of at most `SHELF_PANEL_SEGMENT`
    (`add_segmented_box`; the same solid). Whole, their 0.96-0.99 m bounding spheres outrank
    the pairs that hold the objects on the boards in MJX's `max_geom_pairs` cull
    (experiments/fidelity/pair_cap.py; docs/tasks.md, "Contact sets")."""
    shelf = spec.worldbody.add_body(name="shelf", pos=pos)
    for z in (0.025, 0.325, 0.625, 0.925, 1.225, 1.525):
        add_fixture(spec, shelf, pos=(0, 0, z), size=(0.3, 0.4, 0.025), rgba=WOOD)
    for name, p, half in (("shelf_top", (0.025, 0, 1.825), (0.325, 0.45, 0.025)),
                          ("shelf_side_l", (0.025, 0.425, 0.9), (0.325, 0.025, 0.9)),
                          ("shelf_side_r", (0.025, -0.425, 0.9), (0.325, 0.025, 0.9)),
                          ("shelf_back", (0.325, 0, 0.9), (0.025, 0.4, 0.9))):  # fmt: skip
        add_segmented_box(shelf, name, p, half, SHELF_PANEL_SEGMENT, contype=FIXTURE,
                          conaffinity=0, rgba=WOOD)  # fmt: skip
    return shelf
