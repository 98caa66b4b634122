"""Turn two in-hand cubes to a random target orientation (HumanoidBench Cube)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    body_id,
    euler_to_quat,
    free_joint_adr,
    hand_sites,
)

CUBE_HALF = 0.025
CUBE_DENSITY = 500.0  # 0.0625 kg each
CUBE_POS = ((0.45, 0.21, 1.125), (0.45, -0.21, 1.125))  # HumanoidBench's keyframe, not body pos
TARGET_POS = (0.5, 0.0, 1.5)  # a visual cube; only its orientation matters
EULER_RANGE = 3.14
ROOT_TERMINATION, CUBE_TERMINATION = 0.58, 0.6
_CUBES = ("left_cube_to_rotate", "right_cube_to_rotate")


def cube_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    v_com: jax.Array,
    cube_quats: jax.Array,
    target_quat: jax.Array,
    hands: jax.Array,
    cubes: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Cube: 0.2 small_control * stand_reward * dont_move + 0.5 orientation
    + 0.3 closeness, with orientation = mean over cubes of tol(|q_cube - q_target|, margin 0.3)
    (the raw quaternion difference: q and -q differ) and closeness = mean over the two
    hand/cube pairs of tol(|hand site - cube|, (0, 0.1), margin 0.5).

    Args:
      cube_quats: [2, 4] left, right cube xquat. target_quat: [4].
      hands: [2, 3] left_hand, right_hand sites. cubes: [2, 3] left, right cube xpos.
    """
    standing = R.standing(head_z)
    upright = R.upright(zz, 0.9)
    stand_reward = standing * upright
    small_control = R.small_control(force)
    dont_move = R.dont_move(v_com[:2])
    orientation = jnp.mean(
        R.tolerance(jnp.linalg.norm(cube_quats - target_quat, axis=-1), margin=0.3)
    )
    closeness = jnp.mean(
        R.tolerance(jnp.linalg.norm(hands - cubes, axis=-1), (0.0, 0.1), margin=0.5)
    )
    reward = 0.2 * (small_control * stand_reward * dont_move) + 0.5 * orientation + 0.3 * closeness
    terms = {
        "small_control": small_control,
        "stand_reward": stand_reward,
        "dont_move": dont_move,
        "standing": standing,
        "upright": upright,
        "orientation_alignment_reward": orientation,
        "cube_closeness_reward": closeness,
    }
    return reward, terms


def cube_terminated(root_z: jax.Array, cube_z: jax.Array) -> jax.Array:
    """root z < 0.58 or either cube's z < 0.6. cube_z: [2]."""
    return (root_z < ROOT_TERMINATION) | jnp.any(cube_z < CUBE_TERMINATION)


class CubeTask(ManipulationTask):
    """Two free 5 cm cubes start in front of the hands with random orientations; the target
    orientation (HumanoidBench writes it into the model's `body_quat`) is the task state and the
    last 4 observation entries. No reset noise (HumanoidBench's noise scale is 0 here)."""

    reset_edits = True
    object_qpos = tuple(v for pos in CUBE_POS for v in (*pos, 1.0, 0.0, 0.0, 0.0))
    max_geom_pairs = 8
    name = "cube"
    metric_names = (
        "small_control", "stand_reward", "dont_move", "standing", "upright",
        "orientation_alignment_reward", "cube_closeness_reward",
    )  # fmt: skip
    reset_noise = 0.0
    extra_obs_size = 4

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        for name, pos in zip(_CUBES, CUBE_POS, strict=True):
            cube = spec.worldbody.add_body(name=name, pos=pos)
            cube.add_freejoint(name=f"free_{name}")
            scene.add_mass_geom(cube, CUBE_DENSITY, type=scene.BOX, size=(CUBE_HALF,) * 3,
                                rgba=(0.9, 0.8, 0.2, 1))  # fmt: skip
            scene.add_object_geom(cube, touch_objects=True, type=scene.BOX,
                                  size=(CUBE_HALF,) * 3, density=0.0)  # fmt: skip
        target = spec.worldbody.add_body(name="target_cube", pos=TARGET_POS)
        target.add_geom(type=scene.BOX, size=(CUBE_HALF,) * 3, contype=0, conaffinity=0,
                        group=1, density=0.0, rgba=(1, 1, 1, 0.3))  # fmt: skip

    def bind(self, model, robot) -> None:
        self._cubes = [body_id(model, n) for n in _CUBES]
        self._quat_adr = [free_joint_adr(model, f"free_{n}")[0] + 3 for n in _CUBES]

    def init(self, key, qpos):
        k_left, k_right, k_target = jax.random.split(key, 3)
        for k, adr in zip((k_left, k_right), self._quat_adr, strict=True):
            angles = jax.random.uniform(k, (3,), minval=-EULER_RANGE, maxval=EULER_RANGE)
            qpos = qpos.at[adr : adr + 4].set(euler_to_quat(angles))
        target = jax.random.uniform(k_target, (3,), minval=-EULER_RANGE, maxval=EULER_RANGE)
        return qpos, euler_to_quat(target)

    def evaluate(self, robot, data: mjx.Data, target):
        hands = hand_sites(robot, data)
        cubes = data.xpos[jnp.array(self._cubes)]
        reward, terms = cube_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            robot.com_velocity(data), data.xquat[jnp.array(self._cubes)], target, hands, cubes,
        )  # fmt: skip
        return reward, cube_terminated(data.qpos[2], cubes[:, 2]), target, terms

    def extra_obs(self, robot, data: mjx.Data, target):
        return target
