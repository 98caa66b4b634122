"""Sit on a chair, fixed (sit_simple) or free (sit_hard) (HumanoidBench §3)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.humanoid import Task
from sirl_jax.envs.task_parts import LOCOMOTION_BUDGET, fallen
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.locomotion.obstacles import whole_robot_bits
from sirl_jax.hb_compat import HB

CHAIR_POS = (-0.25, 0.0, 0.0)
# HumanoidBench's chair: massless collision boxes; the mass (15.7 kg) comes from the visual
# boxes at density 1000. (pos, half size) in the chair frame.
_CHAIR_COLLISION = (
    ((-0.23, 0.0, 0.65), (0.02, 0.21, 0.2)),
    ((0.0, 0.0, 0.2375), (0.21, 0.21, 0.2375)),
)
_CHAIR_VISUAL = (
    ((0.19, 0.19, 0.225), (0.02, 0.02, 0.225)),
    ((0.19, -0.19, 0.225), (0.02, 0.02, 0.225)),
    ((-0.19, 0.19, 0.225), (0.02, 0.02, 0.225)),
    ((-0.19, -0.19, 0.225), (0.02, 0.02, 0.225)),
    ((0.0, 0.0, 0.45), (0.21, 0.21, 0.025)),
    ((-0.23, 0.19, 0.6375), (0.02, 0.02, 0.2125)),
    ((-0.23, -0.19, 0.6375), (0.02, 0.02, 0.2125)),
    ((-0.23, 0.0, 0.77), (0.02, 0.21, 0.08)),
)


def sit_reward(
    root: jax.Array,
    chair_xy: jax.Array,
    head_z: jax.Array,
    imu_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    v_com: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Sit: small_control * sit * dont_move with
    sit = (0.5 sitting + 0.5 on_chair) * upright_s * posture,
    sitting = tol(root_z, (0.68, 0.72), 0.2),
    on_chair = tol(root_x - chair_x, (-0.19, 0.19), 0.2) * tol(root_y - chair_y, (0, 0), 0.1),
    posture = tol(head_z - imu_z, (0.35, 0.45), 0.3),
    upright_s = tol(zz, (0.95, inf), 0.9, linear, 0).

    Args:
      root: [3] qpos[0:3]. chair_xy: [2] chair body position.
    """
    sitting = R.tolerance(root[2], (0.68, 0.72), margin=0.2)
    on_chair = R.tolerance(root[0] - chair_xy[0], (-0.19, 0.19), margin=0.2) * R.tolerance(
        root[1] - chair_xy[1], margin=0.1
    )
    posture = R.tolerance(head_z - imu_z, (0.35, 0.45), margin=0.3)
    upright = R.upright(zz, 0.95, margin=0.9)
    sit = (0.5 * sitting + 0.5 * on_chair) * upright * posture
    small_control = R.small_control(force)
    dont_move = R.dont_move(v_com[:2])
    reward = small_control * sit * dont_move
    terms = {
        "small_control": small_control,
        "sit_reward": sit,
        "dont_move": dont_move,
        "sitting": sitting,
        "on_chair": on_chair,
        "upright": upright,
        "sitting_posture": posture,
    }
    return reward, terms


ROOT_X, ROOT_Y, ROOT_YAW = (0.2, 0.4), (-0.15, 0.15), (-1.8, 1.8)
"""sit_hard's uniform reset ranges of the robot's root x, y (m) and yaw (rad)."""


def yaw_quat(yaw: jax.Array) -> jax.Array:
    """[4] (w, x, y, z) rotation by `yaw` about +z (HumanoidBench's euler_to_quat(0, 0, yaw))."""
    return jnp.stack([jnp.cos(yaw / 2), 0.0 * yaw, 0.0 * yaw, jnp.sin(yaw / 2)])


class SitTask(Task):
    """Sit on the chair behind the robot; terminates when the root z < 0.5.

    sit_hard: the chair is free (7 + 6 extra qpos/qvel in the observation) and the robot's root
    is placed at x ~ U(0.2, 0.4), y ~ U(-0.15, 0.15), yaw ~ U(-1.8, 1.8) at reset.
    """

    max_contact_points = LOCOMOTION_BUDGET

    metric_names = (
        "small_control", "sit_reward", "dont_move", "sitting", "on_chair", "upright",
        "sitting_posture",
    )  # fmt: skip

    def __init__(self, name: str):
        if name not in ("sit_simple", "sit_hard"):
            raise ValueError(f"unknown sit task {name!r}; allowed: 'sit_simple', 'sit_hard'")
        self.name = name
        self.free = name == "sit_hard"
        self.reset_edits = self.free  # sit_hard draws the root pose

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        if self.contact_set == HB:  # HumanoidBench: the chair touches the whole robot
            bits = whole_robot_bits(spec, variant)
        else:  # the reduced set: the feet pass through the seat; legs, body and arms touch it
            bits = scene.set_contact_bits(spec, scene.robot_groups(variant),
                                          ("legs", "body", "arms"))  # fmt: skip
        scene.set_max_geom_pairs(spec, 4)
        chair = spec.worldbody.add_body(name="chair", pos=CHAIR_POS)
        if self.free:
            chair.add_freejoint(name="free_chair")
        for pos, size in _CHAIR_VISUAL:
            chair.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=pos, size=size, contype=0,
                           conaffinity=0, group=1, density=1000.0, rgba=(0.8, 0.6, 0.4, 1))
        for pos, size in _CHAIR_COLLISION:
            # A free chair also rests on the floor (floor contype 1).
            chair.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=pos, size=size, contype=bits,
                           conaffinity=1 if self.free else 0, group=3, density=0.0)

    def bind(self, model, robot) -> None:
        self._chair = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "chair")

    def init(self, key, qpos):
        if not self.free:
            return qpos, ()
        kx, ky, kyaw = jax.random.split(key, 3)
        (x0, x1), (y0, y1), (yaw0, yaw1) = ROOT_X, ROOT_Y, ROOT_YAW
        x = jax.random.uniform(kx, (), minval=x0, maxval=x1)
        y = jax.random.uniform(ky, (), minval=y0, maxval=y1)
        yaw = jax.random.uniform(kyaw, (), minval=yaw0, maxval=yaw1)
        qpos = qpos.at[0].set(x).at[1].set(y).at[3:7].set(yaw_quat(yaw))
        return qpos, ()

    def reset_ops(self) -> list[dict]:
        if not self.free:
            return []
        return [{"op": "root_pose_uniform", "x": list(ROOT_X), "y": list(ROOT_Y),
                 "yaw": list(ROOT_YAW)}]  # fmt: skip

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = sit_reward(
            data.qpos[0:3], data.xpos[self._chair, :2], robot.head_height(data),
            robot.site_pos(data, "imu")[2], robot.torso_upright(data),
            robot.actuator_forces(data), robot.com_velocity(data),
        )  # fmt: skip
        return reward, fallen(data.qpos[2], 0.5), task_state, terms



