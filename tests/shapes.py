"""Geometry of MuJoCo primitives shared by the constructed-state tests."""

from __future__ import annotations

import mujoco
import numpy as np


def support(gtype: int, size, pos, mat, u) -> float:
    """The largest u-coordinate of a geom's surface: sphere, capsule or box at `pos`, with axes
    the columns of `mat` [3, 3]."""
    centre, axes = float(np.dot(pos, u)), np.abs(np.asarray(mat).T @ u)
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        return centre + size[0]
    if gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return centre + axes[2] * size[1] + size[0]
    assert gtype == mujoco.mjtGeom.mjGEOM_BOX, gtype
    return centre + float(axes @ size)
