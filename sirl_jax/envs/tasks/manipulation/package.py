"""Carry a package to a random destination on the floor (HumanoidBench Package)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    free_joint_adr,
    hand_sites,
)

PACKAGE_KEY_POS = (0.75, 0.0, 0.35)
PACKAGE_HALF = (0.2, 0.1, 0.35)
PACKAGE_DENSITY = 5.0  # 0.28 kg
XY_RANGE = 2.0
PACKAGE_Z, DESTINATION_Z = 0.35, 0.35  # destination_loc: body z 0 + site 0.35
SUCCESS_DIST, SUCCESS_BONUS = 0.1, 1000.0


def package_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    package: jax.Array,
    destination: jax.Array,
    hands: jax.Array,
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Package: stand_reward * small_control - 3 |pkg - dest|
    - 0.1 (|lh - pkg| + |rh - pkg|) + min(pkg_z, 1) + 1000 [|pkg - dest| < 0.1], with
    stand_reward = standing * upright(0.8).

    Args:
      package: [3] package position (its free joint's qpos). destination: [3].
      hands: [2, 3] left_hand, right_hand sites.

    Returns:
      (reward [], success [] bool (also the termination), terms).
    """
    standing = R.standing(head_z)
    stand_reward = standing * R.upright(zz, 0.8)
    small_control = R.small_control(force)
    dist = jnp.linalg.norm(package - destination)
    hand_left, hand_right = jnp.linalg.norm(hands - package, axis=-1)
    height = jnp.minimum(package[2], 1.0)
    success = dist < SUCCESS_DIST
    reward = (
        stand_reward * small_control
        - 3.0 * dist
        - 0.1 * (hand_left + hand_right)
        + height
        + jnp.where(success, SUCCESS_BONUS, 0.0)
    )
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "dist_package_destination": dist,
        "dist_hand_package_right": hand_right,
        "dist_hand_package_left": hand_left,
        "package_height": height,
        "success": success.astype(jnp.float32),
    }
    return reward, success, terms


class PackageTask(ManipulationTask):
    """A 0.4 x 0.2 x 0.7 m, 0.28 kg package at xy ~ U(-2, 2)^2 (z 0.35) and a destination at
    xy ~ U(-2, 2)^2, z 0.35, the task state; terminates on success. Observation: robot
    qpos/qvel (151), destination, package qpos (7) and qvel (6), both hand sites (173).

    HumanoidBench moves the destination by writing `model.body_pos` after its last forward
    pass, so its reset observation shows the previous episode's destination; here the reset
    observation shows the new one.
    """

    reset_edits = True
    object_qpos = (*PACKAGE_KEY_POS, 1, 0, 0, 0)
    max_geom_pairs = 8
    name = "package"
    metric_names = (
        "stand_reward", "small_control", "dist_package_destination", "dist_hand_package_right",
        "dist_hand_package_left", "package_height", "success",
    )  # fmt: skip
    full_state_obs = False
    extra_obs_size = 22

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        body = spec.worldbody.add_body(name="package_a", pos=PACKAGE_KEY_POS)
        body.add_freejoint(name="free_package")
        scene.add_mass_geom(body, PACKAGE_DENSITY, type=scene.BOX, size=PACKAGE_HALF,
                            rgba=(0.75, 0.6, 0.4, 1))  # fmt: skip
        scene.add_object_geom(body, name="package_a_collision", type=scene.BOX,
                              size=PACKAGE_HALF, density=0.0)  # fmt: skip

    def bind(self, model, robot) -> None:
        self._qpos, self._dof = free_joint_adr(model, "free_package")

    def init(self, key, qpos):
        k_package, k_dest = jax.random.split(key)
        xy = jax.random.uniform(k_package, (2,), minval=-XY_RANGE, maxval=XY_RANGE)
        qpos = qpos.at[self._qpos : self._qpos + 3].set(jnp.append(xy, PACKAGE_Z))
        dest = jax.random.uniform(k_dest, (2,), minval=-XY_RANGE, maxval=XY_RANGE)
        return qpos, jnp.append(dest, DESTINATION_Z)

    def _hands(self, robot, data):
        return hand_sites(robot, data)

    def evaluate(self, robot, data: mjx.Data, destination):
        package = data.qpos[self._qpos : self._qpos + 3]
        reward, success, terms = package_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            package, destination, self._hands(robot, data),
        )  # fmt: skip
        return reward, success, destination, terms

    def extra_obs(self, robot, data: mjx.Data, destination):
        return jnp.concatenate([
            destination,
            data.qpos[self._qpos : self._qpos + 7],
            data.qvel[self._dof : self._dof + 6],
            self._hands(robot, data).reshape(-1),
        ])  # fmt: skip
