"""Goal markers: the goals a task keeps in its state, drawn into the rendered scene only.

A task whose goal is task state (not a body of its model) has nothing in the scene to show it.
`goal_points` reads the goal out of the task state recorded with each rollout step, for the
tasks named in `GOALS` (the layout of each task's state is documented in its module), and
`add_markers` draws each goal as a translucent green sphere with MuJoCo's scene geoms, after
`update_scene`: nothing is added to any model. Tasks not named here draw no marker (the cube's
target orientation is its model's translucent `target_cube`; a task state that is not a goal,
such as window's head position at reset, is never drawn).
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


__all__ = ["GOALS", "add_markers", "goal_points"]
