"""Helpers shared by the task modules: robot collider groups and the fall termination."""

from __future__ import annotations

import functools

import jax

from sirl_jax.envs import h1


@functools.cache
def robot_groups(variant: str) -> dict[str, tuple[str, ...]]:
    """Robot collider names by group ("feet", "legs", "body", "arms"[, "hands"]) of a variant."""
    return dict(h1.Robot(h1.load_model(variant)).geom_groups)


def fallen(qpos_z: jax.Array, threshold: float) -> jax.Array:
    """HumanoidBench's height termination: root z (qpos[2]) < threshold."""
    return qpos_z < threshold
