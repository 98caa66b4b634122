"""Lift a 104 kg dumbbell from the floor to head height (HumanoidBench Powerlift)."""

from __future__ import annotations

import math

import jax
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.task_parts import fallen
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import ManipulationTask, body_id

DUMBBELL_POS = (0.5, 0.0, 0.2)
# (radius, half length, y offset): the bar and the two weights, axes along y; density 1000.
BAR = (0.029, 0.65, 0.0)
WEIGHTS = ((0.2, 0.2, 0.75), (0.2, 0.2, -0.75))
LIFT_BOUNDS, LIFT_MARGIN = (1.9, 2.1), 2.0
ROOT_TERMINATION = 0.2


def powerlift_reward(
    head_z: jax.Array, zz: jax.Array, force: jax.Array, dumbbell_z: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Powerlift: 0.2 small_control * stand_reward + 0.8 lifted, with
    standing = tol(head_z, (1.65, inf), margin 1.65/3), upright = upright(0.8) and
    lifted = tol(dumbbell z, (1.9, 2.1), margin 2) (gaussian)."""
    standing = R.tolerance(head_z, (R.STAND_HEIGHT, math.inf), margin=R.STAND_HEIGHT / 3)
    upright = R.upright(zz, 0.8)
    stand_reward = standing * upright
    small_control = R.small_control(force)
    lifted = R.tolerance(dumbbell_z, LIFT_BOUNDS, margin=LIFT_MARGIN)
    reward = 0.2 * (small_control * stand_reward) + 0.8 * lifted
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "reward_dumbbell_lifted": lifted,
        "standing": standing,
        "upright": upright,
    }
    return reward, terms


class PowerliftTask(ManipulationTask):
    """A free dumbbell (bar r 0.029 x 1.3 m, two weights r 0.2 x 0.4 m; 104 kg) on the floor in
    front of the robot; terminates when the root z < 0.2.

    Colliders (MJX has no cylinder-box pair and the palms are boxes): the bar is a capsule that
    touches the hands and the floor; the weights are cylinders that touch the floor only, and
    in the `hb` contact set 12-sided prisms of the same area that touch the robot too (their
    vertices 4.7 mm outside the 0.2 m circle, their faces 2.3 mm inside).
    HumanoidBench's keyframe gives the dumbbell the quaternion (0, 0, 0, 0), so after reset noise
    its orientation is the normalised noise, i.e. random; here it starts level (1, 0, 0, 0).
    """

    object_qpos = (*DUMBBELL_POS, 1, 0, 0, 0)
    max_geom_pairs = 8
    prism_sides = 12  # 0.28 -> 0.35 of bare against 16 (docs/tasks.md, "Contact budget")
    name = "powerlift"
    metric_names = (
        "stand_reward", "small_control", "reward_dumbbell_lifted", "standing", "upright",
    )  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        body = spec.worldbody.add_body(name="dumbbell", pos=DUMBBELL_POS)
        body.add_freejoint(name="free_dumbbell")
        for radius, half, y in (BAR, *WEIGHTS):
            scene.add_mass_geom(body, 1000.0, type=scene.CYLINDER, size=(radius, half, 0),
                                pos=(0, y, 0), quat=scene.Y_AXIS,
                                rgba=(0.5, 0.5, 0.55, 1))  # fmt: skip
        radius, half, _ = BAR
        scene.add_object_geom(body, name="bar_collision", type=scene.CAPSULE,
                              size=(radius, half, 0), quat=scene.Y_AXIS, density=0.0)  # fmt: skip
        for k, (radius, half, y) in enumerate(WEIGHTS):
            scene.add_object_geom(body, hands=False, name=f"weight_{k}_collision",
                                  type=scene.CYLINDER, size=(radius, half, 0), pos=(0, y, 0),
                                  quat=scene.Y_AXIS, density=0.0)  # fmt: skip

    def bind(self, model, robot) -> None:
        self._dumbbell = body_id(model, "dumbbell")

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = powerlift_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            data.xpos[self._dumbbell, 2],
        )  # fmt: skip
        return reward, fallen(data.qpos[2], ROOT_TERMINATION), task_state, terms
