"""Household objects and furniture shared by HumanoidBench's room and bookshelf scenes.

Each builder adds colliders and mass to a free body the caller made. MJX has no cylinder-box
pair (and refuses a model that has one), while palms, shelves and tables are boxes, so
HumanoidBench's cylinders become: flat discs and ear cups a box of the disc's area and
thickness, long rods a capsule of the same length, a standing can a box of the same area. Mass
and inertia always come from HumanoidBench's own shapes (non-colliding geoms at density 1000,
its "visual" geoms' default), so every object weighs what it does there.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import mujoco

from sirl_jax.envs.tasks import manip

DENSITY = 1000.0
WOOD = (0.55, 0.4, 0.28, 1)
_GREY = {"rgba": (0.59, 0.61, 0.62, 1)}
_RED = {"rgba": (0.25, 0, 0, 1)}


def add_shelf(spec: mujoco.MjSpec, pos: Sequence[float]) -> mujoco.MjsBody:
    """HumanoidBench's shelf (static fixture): six 0.6 x 0.8 m boards 0.3 m apart from z 0,
    a top board, two sides and a back panel at +x."""
    shelf = spec.worldbody.add_body(name="shelf", pos=pos)
    for z in (0.025, 0.325, 0.625, 0.925, 1.225, 1.525):
        manip.add_fixture(spec, shelf, pos=(0, 0, z), size=(0.3, 0.4, 0.025), rgba=WOOD)
    for p, half in (((0.025, 0, 1.825), (0.325, 0.45, 0.025)),
                    ((0.025, 0.425, 0.9), (0.325, 0.025, 0.9)),
                    ((0.025, -0.425, 0.9), (0.325, 0.025, 0.9)),
                    ((0.325, 0, 0.9), (0.025, 0.4, 0.9))):  # fmt: skip
        manip.add_fixture(spec, shelf, pos=p, size=half, rgba=WOOD)
    return shelf


def disc(body: mujoco.MjsBody, pos, radius: float, half: float, quat=(1, 0, 0, 0), **kw) -> None:
    """A cylinder's mass (non-colliding) and a box collider of the disc's area."""
    manip.add_mass_geom(body, DENSITY, type=manip.CYLINDER, pos=pos, size=(radius, half, 0),
                        quat=quat, **kw)  # fmt: skip
    side = radius * math.sqrt(math.pi) / 2
    manip.add_object_geom(body, type=manip.BOX, pos=pos, size=(side, side, half), quat=quat,
                          density=0.0)  # fmt: skip


def rod(body: mujoco.MjsBody, pos, radius: float, half: float, quat=(1, 0, 0, 0), **kw) -> None:
    """A cylinder's mass (non-colliding) and a capsule collider of the cylinder's length."""
    manip.add_mass_geom(body, DENSITY, type=manip.CYLINDER, pos=pos, size=(radius, half, 0),
                        quat=quat, **kw)  # fmt: skip
    manip.add_object_geom(body, type=manip.CAPSULE, pos=pos, size=(radius, half - radius, 0),
                          quat=quat, density=0.0)  # fmt: skip


def trophy(body: mujoco.MjsBody) -> None:
    """1.51 kg: a base disc (r 0.1), a stem (r 0.025, 0.2 m) and a ball (r 0.035) on top."""
    disc(body, (0, 0, 0.015), 0.1, 0.015, **_GREY)
    rod(body, (0, 0, 0.115), 0.025, 0.1, **_GREY)
    manip.add_object_geom(body, type=manip.SPHERE, pos=(0, 0, 0.2), size=(0.035, 0, 0),
                          density=DENSITY, **_GREY)  # fmt: skip


def snow_globe(body: mujoco.MjsBody) -> None:
    """5.13 kg: a base disc (r 0.1) and a globe (r 0.1)."""
    disc(body, (0, 0, 0.015), 0.1, 0.015, **_GREY)
    manip.add_object_geom(body, type=manip.SPHERE, pos=(0, 0, 0.101), size=(0.1, 0, 0),
                          density=DENSITY, rgba=(0.8, 0.9, 1.0, 0.6))  # fmt: skip


def headphone(body: mujoco.MjsBody, y_offset: float = 0.0) -> None:
    """2.91 kg: two ear cups (discs r 0.08 along y), two arms and a band. `y_offset`: room's
    headphone has its geoms in a child body 0.05 m to -y."""
    for y in (-0.07, 0.07):
        disc(body, (0.1, y + y_offset, 0.08), 0.08, 0.025, quat=manip.Y_AXIS, **_RED)
        manip.add_object_geom(body, type=manip.BOX, pos=(0.2, y + y_offset, 0.08),
                              size=(0.1, 0.02, 0.02), density=DENSITY, **_RED)  # fmt: skip
    manip.add_object_geom(body, type=manip.BOX, pos=(0.3, y_offset, 0.08),
                          size=(0.02, 0.08, 0.02), density=DENSITY, **_RED)  # fmt: skip


def box(half: Sequence[float], pos=(0, 0, 0)) -> Callable[[mujoco.MjsBody], None]:
    """A builder of a solid box (a package) at density 1000."""

    def build(body: mujoco.MjsBody) -> None:
        manip.add_object_geom(body, type=manip.BOX, pos=pos, size=half, density=DENSITY,
                              rgba=(0.75, 0.6, 0.4, 1))  # fmt: skip

    return build
