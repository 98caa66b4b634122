"""Catch a ball thrown at the robot and throw it into a hoop (HumanoidBench Basketball)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.overlap import PairQuery
from sirl_jax.envs.task_parts import contact_arrays, fallen, geom_mask
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    body_id,
    free_joint_adr,
    geom_ids,
    hand_sites,
)

BALL_RADIUS = 0.1193
BALL_DENSITY = 35.0  # 0.249 kg
BALL_KEY_POS = (0.35, 0.9, 2.0)
THROW_SPEED, THROW_DISTANCE, THROW_ANGLE = 7.5, 1.5, 1.45
BALL_ABOVE_HAND = 0.3924
HOOP_CENTER = (5.9, 0.0, 2.25)
HOOP_BODY = (6.0198 - 0.2, 0.0, 2.25)  # basketball_hoop (6.0198, 0, 0) + baskethoop (-0.2, 0, 2.25)
# HumanoidBench writes the rim boxes' yaw as euler="0 0 +-45" in a model compiled with
# angle="radian": they are turned by +-45 rad (= -+58.3 deg), kept so here.
_RIM_YAW = 45.0
# (pos, half size, yaw in rad) in the baskethoop frame: 8 rim boxes, backboard, base box.
HOOP_BOXES = (
    ((0.25, 0.0, -0.2), (0.01, 0.2, 0.2), 0.0),
    ((0.2, 0.2, -0.2), (0.15, 0.01, 0.2), -_RIM_YAW),
    ((0.2, -0.2, -0.2), (0.15, 0.01, 0.2), _RIM_YAW),
    ((-0.3, 0.0, -0.2), (0.01, 0.2, 0.2), 0.0),
    ((-0.25, 0.2, -0.2), (0.15, 0.01, 0.2), _RIM_YAW),
    ((-0.25, -0.2, -0.2), (0.15, 0.01, 0.2), -_RIM_YAW),
    ((-0.05, 0.25, -0.2), (0.2, 0.01, 0.2), 0.0),
    ((-0.05, -0.25, -0.2), (0.2, 0.01, 0.2), 0.0),
    ((0.27, 0.0, 0.3), (0.01, 0.55, 0.35), 0.0),
    ((0.9, 0.0, -2.17), (0.35, 0.25, 0.08), 0.0),
)
HOOP_POST = ((0.6, 0.0, -1.25), (0.05, 1.0))  # cylinder (pos, (radius, half length))
SUCCESS_DIST, SUCCESS_BONUS = 0.05, 1000.0
BALL_TERMINATION, ROOT_TERMINATION = 0.5, 0.5
CATCH, THROW = 0, 1


def basketball_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    hands: jax.Array,
    ball: jax.Array,
    hoop: jax.Array,
    touched: jax.Array,
    stage: jax.Array,
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Basketball. The stage turns from catch (0) to throw (1), for good, in the
    step where any active contact involves the ball; that step already pays the throw reward.

    catch: 0.5 stab + 0.5 prox; throw: 0.15 stab + 0.05 prox + 0.8 tol(|ball - hoop|, margin 7,
    linear, vam 0.1); + 1000 when |ball - hoop| < 0.05. stab = standing * upright(0.9) *
    small_control; prox = tol(max over hands |hand site - ball|, (0, 0.2), margin 1).

    Args:
      hands: [2, 3] left_hand, right_hand sites. ball: [3] ball xpos. hoop: [3] hoop_center.
      touched: [] bool, an active contact involves the ball. stage: [] int32.

    Returns:
      (reward [], new stage [] int32, terms).
    """
    stab = R.standing(head_z) * R.upright(zz, 0.9) * R.small_control(force)
    prox = R.tolerance(jnp.max(jnp.linalg.norm(hands - ball, axis=-1)), (0.0, 0.2), margin=1.0)
    hoop_dist = jnp.linalg.norm(ball - hoop)
    toward_hoop = R.tolerance(hoop_dist, margin=7.0, sigmoid="linear")
    new_stage = jnp.where(touched, THROW, stage).astype(jnp.int32)
    success = hoop_dist < SUCCESS_DIST
    reward = jnp.where(
        new_stage == THROW, 0.15 * stab + 0.05 * prox + 0.8 * toward_hoop, 0.5 * stab + 0.5 * prox
    ) + jnp.where(success, SUCCESS_BONUS, 0.0)
    terms = {
        "reward_hand_proximity": prox,
        "reward_ball_success": toward_hoop,
        "stand_reward": R.standing(head_z) * R.upright(zz, 0.9),
        "small_control": R.small_control(force),
        "success_subtasks": new_stage.astype(jnp.float32),
        "success": success.astype(jnp.float32),
    }
    return reward, new_stage, terms


def throw_state(angle: jax.Array, hand_z: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Ball ([3] position, [3] velocity) 1.5 m from the origin at `angle`, 0.3924 m above the
    left hand site, moving at 7.5 m/s toward the z axis (HumanoidBench's `reset_model`)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    pos = jnp.stack([THROW_DISTANCE * c, THROW_DISTANCE * s, BALL_ABOVE_HAND + hand_z])
    vel = jnp.stack([-THROW_SPEED * c, -THROW_SPEED * s, 0.0 * c])
    return pos, vel


def _yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2)))


class BasketballTask(ManipulationTask):
    """A 0.249 kg ball is thrown at the robot from a random angle in (-1.45, 1.45) rad; the stage
    (0 catch, 1 throw) is the task state. Terminates when the ball z < 0.5, the root z < 0.5 or
    the ball is within 0.05 of the hoop centre.

    Contacts: the ball touches the hands, the robot's body and arms (HumanoidBench's ball hits
    the whole robot), the hoop and the floor. The catch stage ends at any active ball contact;
    hb_compat "exact" (HumanoidBench's rule: any ball contact, the whole robot) also ends it
    when the ball overlaps any robot collider (feet, legs, body, arms, hands, links: an exact
    `PairQuery`, since the legs and links do not touch the ball here); "fixed" reads the
    contacts alone.
    """

    reset_edits = True
    object_qpos = (*BALL_KEY_POS, 1, 0, 0, 0)
    max_geom_pairs = 8
    name = "basketball"
    reads_contact_slots = True  # the ball-hand touch
    metric_names = (
        "reward_hand_proximity", "reward_ball_success", "stand_reward", "small_control",
        "success_subtasks", "success",
    )  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        body_bits = scene.set_contact_bits(spec, scene.robot_groups(variant), ("body", "arms"))
        hoop = spec.worldbody.add_body(name="baskethoop", pos=HOOP_BODY)
        for k, (pos, size, yaw) in enumerate(HOOP_BOXES):
            scene.add_fixture(spec, hoop, name=f"hoop_{k}_collision", pos=pos, size=size,
                              quat=_yaw_quat(yaw), rgba=(0.9, 0.4, 0.1, 0.6))  # fmt: skip
        pos, size = HOOP_POST
        scene.add_fixture(spec, hoop, name="hoop_post_collision", type=scene.CYLINDER, pos=pos,
                          size=(*size, 0), rgba=(0.3, 0.3, 0.3, 1))  # fmt: skip
        spec.worldbody.add_site(name="hoop_center", pos=HOOP_CENTER)
        ball = spec.worldbody.add_body(name="basketball", pos=BALL_KEY_POS)
        ball.add_freejoint(name="free_basketball")
        scene.add_mass_geom(ball, BALL_DENSITY, type=scene.SPHERE, size=(BALL_RADIUS, 0, 0),
                            rgba=(0.9, 0.45, 0.1, 1))  # fmt: skip
        geom = scene.add_object_geom(ball, name="basketball_collision", type=scene.SPHERE,
                                     size=(BALL_RADIUS, 0, 0), density=0.0)  # fmt: skip
        geom.contype |= body_bits

    def bind(self, model, robot) -> None:
        self._ball = body_id(model, "basketball")
        self._qpos, self._dof = free_joint_adr(model, "free_basketball")
        ball_geom = geom_ids(model, ["basketball_collision"])
        self._ball_mask = jnp.asarray(geom_mask(model, ball_geom))
        self._hoop = robot.site_ids["hoop_center"]
        robot_geoms = np.concatenate(list(robot.geom_ids.values()))
        self._ball_robot = PairQuery(model, ball_geom, robot_geoms)

    def init(self, key, qpos):
        k_angle, k_sign = jax.random.split(key)
        sign = jnp.where(jax.random.bernoulli(k_sign), 1.0, -1.0)
        angle = jax.random.uniform(k_angle, ()) * THROW_ANGLE * sign
        return qpos, {"stage": jnp.asarray(CATCH, jnp.int32), "angle": angle}

    def after_reset(self, robot, data: mjx.Data, task_state):
        pos, vel = throw_state(task_state["angle"], robot.site_pos(data, "left_hand")[2])
        qpos = data.qpos.at[self._qpos : self._qpos + 3].set(pos)
        qvel = data.qvel.at[self._dof : self._dof + 3].set(vel)
        return data.replace(qpos=qpos, qvel=qvel), task_state

    def evaluate(self, robot, data: mjx.Data, task_state):
        hands = hand_sites(robot, data)
        ball = data.xpos[self._ball]
        hoop = data.site_xpos[self._hoop]
        touched = R.any_contact(*contact_arrays(data), self._ball_mask)
        if self.exact:
            touched = touched | self._ball_robot.any(data)
        reward, stage, terms = basketball_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            hands, ball, hoop, touched, task_state["stage"],
        )  # fmt: skip
        terminated = (
            (data.qpos[self._qpos + 2] < BALL_TERMINATION)
            | fallen(data.qpos[2], ROOT_TERMINATION)
            | (terms["success"] > 0)
        )
        return reward, terminated, {**task_state, "stage": stage}, terms
