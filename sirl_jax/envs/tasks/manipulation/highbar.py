"""Swing up to a handstand on a fixed high bar (HumanoidBench HighBarHard, robot h1strong)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import ManipulationTask

BAR_POS = (0.31, 0.0, 2.8)  # the holding bar's axis (body at x 0.5, geom at x -0.19), along y
BAR_RADIUS, BAR_HALF = 0.02, 1.2
POSTS_Y, POST_HALF = 1.2, 2.0  # the two vertical supports: cylinders r 0.02 from z 0 to 4
FEET_BOUND, FEET_MARGIN = 4.8, 2.0
HEAD_TERMINATION = 2.0

# HumanoidBench's keyframe: hanging from the bar, arms overhead, fingers closed around it.
_ARM = {"left": (0.0, 3.11, 0.0, 1.6, 0.0), "right": (0.0, -3.11, 0.0, 1.6, 0.0)}
_HAND = (
    0.11, 0.33, 0, 1.3, 0.7, 1.7, 0, 1.3, 0.7, 1.7, 0, 1.3, 0.7, 1.7,
    0.1, 0, 1.2, 0.77, 1.62, 0.31, 1.35, 0.27, 0.27, 1.45,
)  # fmt: skip
ROBOT_QPOS = (0.27, 0.0, 1.62, 1, 0, 0, 0) + (0.0,) * 11 + (
    *_ARM["left"], *_HAND, *_ARM["right"], *_HAND,
)  # fmt: skip


def highbar_reward(
    zz: jax.Array, feet_z: jax.Array, force: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench HighBar: upright * feet * small_control, with
    upright = tol(-torso zz, (0.9, inf), margin 1.9, linear) (head down) and
    feet = (1 + tol(mean foot z, (4.8, inf), margin 2, linear)) / 2.

    Args:
      zz: [] torso zz. feet_z: [2] left, right foot site z. force: [nu] actuator forces.
    """
    upright = R.tolerance(-zz, (0.9, math.inf), margin=1.9, sigmoid="linear", value_at_margin=0)
    feet = R.tolerance(
        jnp.mean(feet_z), (FEET_BOUND, math.inf), margin=FEET_MARGIN, sigmoid="linear",
        value_at_margin=0,
    )  # fmt: skip
    feet = (1.0 + feet) / 2.0
    small_control = R.small_control(force)
    terms = {"upright_reward": upright, "feet_reward": feet, "small_control": small_control}
    return upright * feet * small_control, terms


class HighBarTask(ManipulationTask):
    """The robot hangs from a fixed bar (2.8 m up) by both hands; reward for a head-down
    handstand above it; terminates when the head drops below 2 m. No reset noise (HumanoidBench
    sets its noise scale to 0 here). Observation: the robot's qpos and qvel (151).

    Colliders: the holding bar is a capsule that touches the hands and the robot's body, legs and
    arms (MJX has no cylinder-box pair, and the palms are boxes); the supports are visual only
    (1.2 m to either side, nothing reaches them)."""

    robot_qpos = ROBOT_QPOS
    max_geom_pairs = 16
    name = "highbar_hard"
    metric_names = ("upright_reward", "feet_reward", "small_control")
    reset_noise = 0.0

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        bar = spec.worldbody.add_body(name="athletic_high_bar", pos=(0.5, 0.0, 0.0))
        x = BAR_POS[0] - 0.5
        for y in (POSTS_Y, -POSTS_Y):
            bar.add_geom(type=scene.CYLINDER, size=(BAR_RADIUS, POST_HALF, 0), pos=(x, y, 2.0),
                         contype=0, conaffinity=0, group=1, rgba=(0.2, 0.2, 0.2, 1))  # fmt: skip
        # touches the hands (scene.HANDS) and the rest of the robot (the floor's bits)
        bar.add_geom(name="holding_bar_collision", type=scene.CAPSULE,
                     size=(BAR_RADIUS, BAR_HALF, 0), pos=(x, 0.0, BAR_POS[2]), quat=scene.Y_AXIS,
                     contype=scene.HANDS | scene.FLOOR, conaffinity=0, group=3,
                     rgba=(0.7, 0.7, 0.72, 1))  # fmt: skip

    def evaluate(self, robot, data: mjx.Data, task_state):
        feet_z = jnp.stack([robot.site_pos(data, s)[2] for s in ("left_foot", "right_foot")])
        reward, terms = highbar_reward(
            robot.torso_upright(data), feet_z, robot.actuator_forces(data)
        )
        return reward, robot.head_height(data) < HEAD_TERMINATION, task_state, terms
