"""Open a sprung door by its handle and walk through it (HumanoidBench Door)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.task_parts import budget_for
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    body_id,
    hand_sites,
)

DOOR_POS = (0.8, 0.0, 0.0)
DOOR_HALF = (0.07, 0.48, 0.99)  # at (0, 0, 1) in the door body; density 600: 159.7 kg
DOOR_DENSITY = 600.0
HINGE_POS, HINGE_RANGE, HINGE_STIFFNESS = (-0.05, -0.5, 1.0), (0.0, 1.4), 50.0
HATCH_POS, HATCH_RANGE, HATCH_STIFFNESS = (0.0, 0.4, 1.2), (0.0, 2.0), 2.0
HANDLE_DENSITY = 1000.0  # the visual geoms' default: the hatch weighs 2.16 kg
# The hatch (the handle, on a hinge along x, gravity-compensated): cylinders
# (pos, radius, half length, axis): the two hubs, the two grips and the two lock pins.
_HATCH = (
    ((-0.12, 0.0, 0.0), 0.05, 0.05, "x"), ((0.12, 0.0, 0.0), 0.05, 0.05, "x"),
    ((-0.141, -0.1, 0.0), 0.02, 0.1, "y"), ((0.141, -0.1, 0.0), 0.02, 0.1, "y"),
    ((0.15, 0.07, 0.0), 0.01, 0.07, "y"), ((-0.15, 0.07, 0.0), 0.01, 0.07, "y"),
)  # fmt: skip
# Static walls in the door body's frame (pos, half size): the door frame's two posts and lintel,
# then the corridor the robot starts in (left, right and back walls).
_WALLS = (
    ((0, 0.66, 1), (0.12, 0.14, 1)), ((0, -0.66, 1), (0.12, 0.14, 1)),
    ((0, 0, 2.19), (0.12, 0.82, 0.19)),
    ((-1.31, -0.7, 1.19), (1.19, 0.12, 1.19)), ((-1.31, 0.7, 1.19), (1.19, 0.12, 1.19)),
    ((-2.35, 0, 1.19), (0.15, 0.58, 1.19)),
)  # fmt: skip
SEGMENT = 0.6
"""m: the door panel and the corridor walls are cut into pieces no longer than this, so that
MJX's cull ranks the pairs that touch over the far parts of a large box (`pair_cap`)."""
PASSAGE_X, PASSAGE_MARGIN = 1.2, 1.0
HATCH_OPEN, HATCH_MARGIN = (0.75, 2.0), 0.75
HAND_BOUND, HAND_MARGIN = 0.25, 1.0
ROOT_TERMINATION = 0.58
_AXES = {"x": scene.X_AXIS, "y": scene.Y_AXIS}


def door_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    door_q: jax.Array,
    hatch_q: jax.Array,
    hatch: jax.Array,
    hands: jax.Array,
    imu_x: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Door: 0.1 stand * small_control + 0.45 min(1, q_door |q_door|)
    + 0.05 tol(q_hatch, (0.75, 2), margin 0.75, linear) + 0.05 proximity + 0.35 passage, with
    upright = tol(zz, (0.9, inf), margin 0.9, linear) (0.9 here, 1.9 in the other tasks),
    proximity = tol(min over hands of |hand - hatch|, (0, 0.25), margin 1, linear) and
    passage = tol(imu x, (1.2, inf), margin 1, linear, value 0 at the margin).

    Args:
      door_q, hatch_q: [] the two hinge angles. hatch: [3] the hatch body. hands: [2, 3].
      imu_x: [] x of the imu site.
    """
    stand_reward = R.standing(head_z) * R.upright(zz, 0.9, margin=0.9)
    small_control = R.small_control(force)
    openness = jnp.minimum(1.0, door_q * jnp.abs(door_q))
    hatch_open = R.tolerance(hatch_q, HATCH_OPEN, margin=HATCH_MARGIN, sigmoid="linear")
    proximity = R.tolerance(
        jnp.min(jnp.linalg.norm(hands - hatch, axis=-1)), (0.0, HAND_BOUND), margin=HAND_MARGIN,
        sigmoid="linear",
    )  # fmt: skip
    passage = R.tolerance(imu_x, (PASSAGE_X, math.inf), margin=PASSAGE_MARGIN, sigmoid="linear",
                          value_at_margin=0.0)  # fmt: skip
    reward = (
        0.1 * stand_reward * small_control + 0.45 * openness + 0.05 * hatch_open
        + 0.05 * proximity + 0.35 * passage
    )  # fmt: skip
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "door_openness_reward": openness,
        "door_hatch_openness_reward": hatch_open,
        "hand_hatch_proximity_reward": proximity,
        "passage_reward": passage,
    }
    return reward, terms


class DoorTask(ManipulationTask):
    """A 160 kg door 0.8 m ahead, on a sprung hinge (stiffness 50, opening toward the robot, 0 to
    1.4 rad), with a sprung handle (the hatch, 0 to 2 rad); the robot starts in a walled corridor.
    Terminates when the root drops below 0.58 m. Observation: full qpos and qvel (155).

    Contacts: the door, the handle and the walls touch every robot collider, the hand colliders
    included (HumanoidBench's full collision between robot and scene: its palms touch the
    corridor walls). The panel and the walls are cut into `SEGMENT` pieces. MJX has no
    cylinder-box pair (it refuses such a model), so the handle's grips and pins are capsules of
    the cylinders' length and its two hubs (r 0.05 cylinders as long as wide) are spheres of
    their radius; the mass and inertia come from HumanoidBench's cylinders (non-colliding
    geoms)."""

    object_qpos = (0.0, 0.0)  # the door and hatch hinges
    max_geom_pairs = 48  # the walls' cull: docs/tasks.md, "Contact budget"
    max_contact_points = budget_for(61)  # its most active contacts (pair_cap)
    name = "door"
    metric_names = (
        "stand_reward", "small_control", "door_openness_reward", "door_hatch_openness_reward",
        "hand_hatch_proximity_reward", "passage_reward",
    )  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        touch_all = scene.FLOOR | scene.HANDS  # robot colliders' conaffinity 1, hands' HANDS
        door = spec.worldbody.add_body(name="door", pos=DOOR_POS)
        door.add_joint(name="door_hinge", pos=HINGE_POS, axis=(0, 0, 1), range=HINGE_RANGE,
                       limited=mujoco.mjtLimited.mjLIMITED_TRUE, stiffness=HINGE_STIFFNESS)
        scene.add_mass_geom(door, DOOR_DENSITY, type=scene.BOX, pos=(0, 0, 1), size=DOOR_HALF,
                            rgba=(0.8, 0.8, 0.83, 1))  # fmt: skip
        scene.add_segmented_box(door, "door_collision", (0, 0, 1), DOOR_HALF, SEGMENT,
                                contype=touch_all, conaffinity=0, density=0.0)  # fmt: skip
        hatch = door.add_body(name="door_hatch", pos=HATCH_POS, gravcomp=1.0)
        hatch.add_joint(name="door_hatch_hinge", axis=(1, 0, 0), range=HATCH_RANGE,
                        limited=mujoco.mjtLimited.mjLIMITED_TRUE, stiffness=HATCH_STIFFNESS)
        for pos, radius, half, axis in _HATCH:
            scene.add_mass_geom(hatch, HANDLE_DENSITY, type=scene.CYLINDER, pos=pos,
                                size=(radius, half, 0), quat=_AXES[axis],
                                rgba=(0.6, 0.6, 0.62, 1))  # fmt: skip
            gtype, size = scene.CAPSULE, (radius, half - radius, 0)
            if half <= radius:  # the hubs: as long as wide
                gtype, size = scene.SPHERE, (radius, 0, 0)
            hatch.add_geom(type=gtype, pos=pos, size=size, quat=_AXES[axis], contype=touch_all,
                           conaffinity=0, group=3, density=0.0)  # fmt: skip
        walls = spec.worldbody.add_body(name="door_walls", pos=DOOR_POS)
        for k, (pos, half) in enumerate(_WALLS):  # every robot collider, hands included
            scene.add_segmented_box(walls, f"wall_{k}", pos, half, SEGMENT,
                                    contype=touch_all, conaffinity=0, rgba=(0.8, 0.8, 0.83, 0.3))

    def bind(self, model, robot) -> None:
        self._door_q = int(model.jnt_qposadr[model.joint("door_hinge").id])
        self._hatch_q = int(model.jnt_qposadr[model.joint("door_hatch_hinge").id])
        self._hatch = body_id(model, "door_hatch")

    def evaluate(self, robot, data: mjx.Data, task_state):
        hands = hand_sites(robot, data)
        reward, terms = door_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            data.qpos[self._door_q], data.qpos[self._hatch_q], data.xpos[self._hatch], hands,
            robot.site_pos(data, "imu")[0],
        )  # fmt: skip
        return reward, data.qpos[2] < ROOT_TERMINATION, task_state, terms
