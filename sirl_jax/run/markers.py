"""Scene additions drawn after `update_scene`: goal markers and blob shadows (no model changes).

Goal markers: the goals a task keeps in its state.
A task whose goal is task state (not a body of its model) has nothing in the scene to show it.
`goal_points` reads the goal out of the task state recorded with each rollout step, for the
tasks named in `GOALS` (the layout of each task's state is documented in its module), and
`add_markers` draws each goal as a translucent green sphere with MuJoCo's scene geoms, after
`update_scene`: nothing is added to any model. Tasks not named here draw no marker (the cube's
target orientation is its model's translucent `target_cube`; a task state that is not a goal,
such as window's head position at reset, is never drawn).

Blob shadows (`add_blob_shadows`): MuJoCo's shadow maps draw the scene twice and cost about
2.5x the frame on a software rasteriser, so by default `render` draws none and grounds the
robot with translucent dark discs on the floor under the pelvis and each foot instead, fading
as the body rises.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

GOAL_RGBA = (0.15, 0.85, 0.3, 0.55)
GOAL_RADIUS = 0.05


def _vector(state) -> np.ndarray:
    return np.asarray(state, np.float64).reshape(1, 3)


def _current_goal(state) -> np.ndarray:
    return np.asarray(state["goals"], np.float64)[int(state["index"])][None]


GOALS: dict[str, Callable] = {
    "reach": _vector,  # the left hand's goal, [3]
    "push": _vector,  # the box's goal on the table, [3]
    "package": _vector,  # the package's destination, [3]
    "bookshelf_simple": _current_goal,  # goals [K, 3], the current item's index
    "bookshelf_hard": _current_goal,
}
"""Task name (`Task.name`) -> function of one step's task state -> goal points [M, 3]."""


def goal_points(env, task_state) -> np.ndarray:
    """The goal points [M, 3] of one step's task state (M = 0 for a task without markers)."""
    reader = GOALS.get(getattr(getattr(env, "task", None), "name", None))
    return np.zeros((0, 3)) if reader is None or task_state is None else reader(task_state)


def add_markers(scene, points: np.ndarray, rgba=GOAL_RGBA, radius: float = GOAL_RADIUS) -> int:
    """Appends one sphere per point to an updated `MjvScene`; returns how many fitted."""
    import mujoco

    added = 0
    for p in points:
        if scene.ngeom >= scene.maxgeom:
            break
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE,
                            np.array([radius, 0.0, 0.0]), np.asarray(p, np.float64),
                            np.eye(3).ravel(), np.asarray(rgba, np.float32))  # fmt: skip
        scene.ngeom += 1
        added += 1
    return added


# body -> (half-lengths x, y of the disc in metres, opacity on the floor, height at which it
# has faded out)
BLOBS = {
    "pelvis": ((0.28, 0.22), 0.28, 2.0),
    "left_ankle_link": ((0.13, 0.06), 0.45, 0.4),
    "right_ankle_link": ((0.13, 0.06), 0.45, 0.4),
}


def add_blob_shadows(scene, model, data, floor_z: float = 0.0) -> int:
    """Appends a flat dark ellipse on the floor under each body of `BLOBS` the model has, turned
    with the body's heading and fading with its height; returns how many it drew."""
    import mujoco

    added = 0
    for name, ((sx, sy), alpha, fade) in BLOBS.items():
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body < 0 or scene.ngeom >= scene.maxgeom:
            continue
        x, y, z = data.xpos[body]
        fwd = data.xmat[body].reshape(3, 3)[:2, 0]
        yaw = float(np.arctan2(fwd[1], fwd[0])) if np.hypot(*fwd) > 1e-6 else 0.0
        c, s = np.cos(yaw), np.sin(yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        strength = alpha * float(np.clip(1.0 - (z - floor_z) / fade, 0.0, 1.0))
        if strength <= 0.0:
            continue
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_ELLIPSOID,
                            np.array([sx, sy, 0.001]), np.array([x, y, floor_z + 0.002]),
                            rot.ravel(), np.array([0.0, 0.0, 0.0, strength], np.float32))
        scene.ngeom += 1
        added += 1
    return added


__all__ = ["BLOBS", "GOALS", "add_blob_shadows", "add_markers", "goal_points"]
