"""The small objects of bookshelf and room, built from the scene vocabulary: each a builder of
one body's geoms (a non-colliding mass geom where the collider is a cheaper shape)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import mujoco

from sirl_jax.envs.tasks.scene import (
    BOX,
    CAPSULE,
    CYLINDER,
    DENSITY,
    SPHERE,
    Y_AXIS,
    add_mass_geom,
    add_object_geom,
)

_GREY = {"rgba": (0.59, 0.61, 0.62, 1)}
_RED = {"rgba": (0.25, 0, 0, 1)}


def disc(body: mujoco.MjsBody, pos, radius: float, half: float, quat=(1, 0, 0, 0), **kw) -> None:
    """A cylinder's mass (non-colliding) and a box collider of the disc's area."""
    add_mass_geom(body, DENSITY, type=CYLINDER, pos=pos, size=(radius, half, 0),
                        quat=quat, **kw)  # fmt: skip
    side = radius * math.sqrt(math.pi) / 2
    add_object_geom(body, type=BOX, pos=pos, size=(side, side, half), quat=quat,
                          density=0.0)  # fmt: skip


def rod(body: mujoco.MjsBody, pos, radius: float, half: float, quat=(1, 0, 0, 0), **kw) -> None:
    """A cylinder's mass (non-colliding) and a capsule collider of the cylinder's length."""
    add_mass_geom(body, DENSITY, type=CYLINDER, pos=pos, size=(radius, half, 0),
                        quat=quat, **kw)  # fmt: skip
    add_object_geom(body, type=CAPSULE, pos=pos, size=(radius, half - radius, 0),
                          quat=quat, density=0.0)  # fmt: skip


def trophy(body: mujoco.MjsBody) -> None:
    """1.51 kg: a base disc (r 0.1), a stem (r 0.025, 0.2 m) and a ball (r 0.035) on top."""
    disc(body, (0, 0, 0.015), 0.1, 0.015, **_GREY)
    rod(body, (0, 0, 0.115), 0.025, 0.1, **_GREY)
    add_object_geom(body, type=SPHERE, pos=(0, 0, 0.2), size=(0.035, 0, 0),
                          density=DENSITY, **_GREY)  # fmt: skip


def snow_globe(body: mujoco.MjsBody) -> None:
    """5.13 kg: a base disc (r 0.1) and a globe (r 0.1)."""
    disc(body, (0, 0, 0.015), 0.1, 0.015, **_GREY)
    add_object_geom(body, type=SPHERE, pos=(0, 0, 0.101), size=(0.1, 0, 0),
                          density=DENSITY, rgba=(0.8, 0.9, 1.0, 0.6))  # fmt: skip


def headphone(body: mujoco.MjsBody, y_offset: float = 0.0) -> None:
    """2.91 kg: two ear cups (discs r 0.08 along y), two arms and a band. `y_offset`: room's
    headphone has its geoms in a child body 0.05 m to -y."""
    for y in (-0.07, 0.07):
        disc(body, (0.1, y + y_offset, 0.08), 0.08, 0.025, quat=Y_AXIS, **_RED)
        add_object_geom(body, type=BOX, pos=(0.2, y + y_offset, 0.08),
                              size=(0.1, 0.02, 0.02), density=DENSITY, **_RED)  # fmt: skip
    add_object_geom(body, type=BOX, pos=(0.3, y_offset, 0.08),
                          size=(0.02, 0.08, 0.02), density=DENSITY, **_RED)  # fmt: skip


def box(half: Sequence[float], pos=(0, 0, 0)) -> Callable[[mujoco.MjsBody], None]:
    """A builder of a solid box (a package) at density 1000."""

    def build(body: mujoco.MjsBody) -> None:
        add_object_geom(body, type=BOX, pos=pos, size=half, density=DENSITY,
                              rgba=(0.75, 0.6, 0.4, 1))  # fmt: skip

    return build
