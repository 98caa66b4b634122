"""What the HumanoidBench tasks share besides `humanoid.Task`: the contact budget rule and its
two defaults, and the contact, geom-mask and height-termination helpers their rewards use."""

from __future__ import annotations

import jax
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs import physics as _physics


def budget_for(max_active: int) -> int:
    """A task's MJX contact budget from the most active contacts measured on it (`pair_cap`,
    random-action states, hands on the floor): the smallest multiple of 32, at least 64, that
    is 20 or more above `max_active` (docs/tasks.md, "Contact budget")."""
    return max(64, -(-(max_active + 20) // 32) * 32)


LOCOMOTION_BUDGET = budget_for(43)
"""The locomotion tasks' MJX contact budget (64). With all 62 hand colliders on the floor (the
`hand_floor` default) walk has 181 contact slots and steps at 0.54 of the bare hands-off
robot's rate; with the solver seeing the 64 most penetrating contacts, 0.79. Random-action
states of 11 locomotion tasks hold at most 43 active contacts (balance_hard; the others 11-31;
`pair_cap`, docs/tasks.md, "Hands on the floor"); a step that fills the budget is reported
(`physics_overflow`)."""
MANIPULATION_BUDGET = budget_for(44)
"""The manipulation tasks' MJX contact budget (64) unless a task's measured maximum needs
more (`budget_for`). With all 62 hand colliders on the floor their scenes allocate 236-627
contact slots, and random-action states hold at most 15-104 active contacts (`pair_cap`)."""


def contact_arrays(data: mjx.Data) -> tuple[jax.Array, jax.Array]:
    """(dist [C], geom [C, 2]) of one env's contacts, either impl (`physics.contact_arrays`)."""
    return _physics.contact_arrays(data)


def geom_mask(model: mujoco.MjModel, ids) -> np.ndarray:
    """[ngeom] bool mask with True at `ids` (geom ids; -1, a name lookup that failed, raises)."""
    ids = np.asarray(list(ids), int)
    if (ids < 0).any() or (ids >= model.ngeom).any():
        raise ValueError(f"geom ids must be in [0, {model.ngeom}), got {ids.tolist()}")
    mask = np.zeros(model.ngeom, bool)
    mask[ids] = True
    return mask


def fallen(qpos_z: jax.Array, threshold: float) -> jax.Array:
    """HumanoidBench's height termination: root z (qpos[2]) < threshold."""
    return qpos_z < threshold
