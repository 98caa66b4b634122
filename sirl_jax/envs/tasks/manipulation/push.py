"""Push a box on a table to a random goal with the left hand (HumanoidBench Push)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    free_joint_adr,
    with_robot_entries,
)

TABLE_POS = (0.9, 0.0, 0.45)
TABLE_TOP = (0.5, 1.0, 0.05)  # half size; top surface at z 0.9
BOX_POS = (0.7, 0.0, 1.0)
BOX_HALF = 0.1
BOX_MASS = 0.3
GOAL_LOW, GOAL_HIGH = (0.7, -0.5), (1.0, 0.5)
GOAL_Z = 1.0
SUCCESS_DIST = 0.05
HAND_DIST_COEF, TARGET_DIST_COEF, SUCCESS_BONUS = 0.1, 1.0, 1000.0
# HumanoidBench's push keyframe: qpos[22] (left wrist yaw) and qpos[47] (right shoulder pitch) are
# 1.57 (index 47 is the right shoulder pitch, not the right wrist yaw at 51; kept as it is).
ROBOT_QPOS = with_robot_entries({22: 1.57, 47: 1.57})


def push_reward(
    hand: jax.Array, box: jax.Array, goal: jax.Array
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Push: -0.1 |hand - box| - |box - goal| + 1000 [|box - goal| < 0.05].

    Args:
      hand: [3] left_hand site. box: [3] box position (its free joint's qpos). goal: [3].

    Returns:
      (reward [], success [] bool (also the termination), terms).
    """
    goal_dist = jnp.linalg.norm(box - goal)
    hand_dist = jnp.linalg.norm(hand - box)
    success = goal_dist < SUCCESS_DIST
    bonus = jnp.where(success, SUCCESS_BONUS, 0.0)
    reward = -HAND_DIST_COEF * hand_dist - TARGET_DIST_COEF * goal_dist + bonus
    terms = {"target_dist": goal_dist, "hand_dist": hand_dist, "reward_success": bonus,
             "success": success.astype(jnp.float32)}  # fmt: skip
    return reward, success, terms


class PushTask(ManipulationTask):
    """Box (0.2 m cube, 0.3 kg) on a table; goal xy ~ U([0.7, -0.5], [1.0, 0.5]), z 1; the goal is
    the task state; terminates on success. Observation: robot qpos/qvel (151), left_hand site,
    goal, box position, box linear velocity (163)."""

    reset_edits = True
    robot_qpos = ROBOT_QPOS
    object_qpos = (*BOX_POS, 1, 0, 0, 0)
    max_geom_pairs = 8
    name = "push"
    metric_names = ("target_dist", "hand_dist", "reward_success", "success")
    full_state_obs = False
    extra_obs_size = 12

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        scene.add_table(spec, TABLE_POS, TABLE_TOP)
        box = spec.worldbody.add_body(name="object", pos=BOX_POS)
        box.add_freejoint(name="free_object")
        scene.set_inertial(box, BOX_MASS, (1e-3, 1e-3, 1e-3))
        scene.add_object_geom(box, name="object_collision", type=scene.BOX, size=(BOX_HALF,) * 3,
                              density=0.0, rgba=(0.67, 0.73, 0.78, 1))  # fmt: skip

    def bind(self, model, robot) -> None:
        self._box_qpos, self._box_dof = free_joint_adr(model, "free_object")

    def init(self, key, qpos):
        xy = jax.random.uniform(key, (2,), minval=jnp.array(GOAL_LOW), maxval=jnp.array(GOAL_HIGH))
        return qpos, jnp.concatenate([xy, jnp.array([GOAL_Z])])

    def _box(self, data: mjx.Data) -> jax.Array:
        return data.qpos[self._box_qpos : self._box_qpos + 3]

    def evaluate(self, robot, data: mjx.Data, goal):
        hand = robot.site_pos(data, "left_hand")
        reward, success, terms = push_reward(hand, self._box(data), goal)
        return reward, success, goal, terms

    def extra_obs(self, robot, data: mjx.Data, goal):
        box_vel = data.qvel[self._box_dof : self._box_dof + 3]
        return jnp.concatenate([robot.site_pos(data, "left_hand"), goal, self._box(data), box_vel])
