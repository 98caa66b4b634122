"""Flat-ground and tunnel tasks: stand, walk, run, crawl, reach (HumanoidBench §3).

Each task's reward is a pure function of the quantities it uses (`*_reward`), so it can be
checked against hand-computed values; the `Task` classes only read those quantities from MJX data.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.humanoid import Task
from sirl_jax.envs.task_parts import LOCOMOTION_BUDGET
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.locomotion.obstacles import whole_robot_bits
from sirl_jax.hb_compat import HB


def walk_reward(
    head_z: jax.Array, zz: jax.Array, force: jax.Array, v_com: jax.Array, speed: float
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Stand (speed 0), Walk (1) and Run (5).

    stand: small_control * standing * upright(0.9) * dont_move
    walk/run: small_control * standing * upright(0.9) * move(speed)

    Args:
      head_z: [] head site height. zz: [] torso_link xmat[2, 2]. force: [nu] actuator forces.
      v_com: [3] robot CoM velocity (world frame).
    """
    standing = R.standing(head_z)
    upright = R.upright(zz, 0.9)
    small_control = R.small_control(force)
    if speed == 0:
        motion = R.dont_move(v_com[:2])
        name = "dont_move"
    else:
        motion = R.move(v_com[0], speed)
        name = "move"
    reward = small_control * standing * upright * motion
    terms = {"standing": standing, "upright": upright, "small_control": small_control, name: motion}
    return reward, terms


def crawl_reward(
    head_z: jax.Array,
    imu: jax.Array,
    pelvis_quat: jax.Array,
    force: jax.Array,
    v_com: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Crawl.

    (0.1 small_control + 0.25 min(crawling, crawling_head) + 0.4 move(1) + 0.25 quat) * in_tunnel,
    crawling = tol(imu_z, (0.6, 1.0), 1), crawling_head = tol(head_z, (0.6, 1.0), 1),
    quat = tol(|pelvis xquat - (0.75, 0, 0.65, 0)|, (0, 0), 1), in_tunnel = [imu_y in [-1, 1]].

    Args:
      imu: [3] imu site position. pelvis_quat: [4] pelvis xquat (w, x, y, z).
    """
    lo, hi = R.CRAWL_HEIGHT - 0.2, R.CRAWL_HEIGHT + 0.2
    small_control = R.small_control(force)
    move = R.move(v_com[0], R.WALK_SPEED)
    crawling_head = R.tolerance(head_z, (lo, hi), margin=1.0)
    crawling = R.tolerance(imu[2], (lo, hi), margin=1.0)
    target = jnp.array([0.75, 0.0, 0.65, 0.0], jnp.float32)
    quat = R.tolerance(jnp.linalg.norm(pelvis_quat - target), margin=1.0)
    in_tunnel = R.tolerance(imu[1], (-1.0, 1.0), margin=0.0)
    reward = (
        0.1 * small_control + 0.25 * jnp.minimum(crawling, crawling_head) + 0.4 * move + 0.25 * quat
    ) * in_tunnel
    terms = {
        "small_control": small_control,
        "move": move,
        "crawling": crawling,
        "crawling_head": crawling_head,
        "pelvis_quat": quat,
        "in_tunnel": in_tunnel,
    }
    return reward, terms


def reach_reward(
    pelvis_zz: jax.Array, robot_qvel: jax.Array, hand: jax.Array, goal: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Reach: 5 pelvis_zz - 1e-4 |qvel|^2 + 5 [d < 1] + 10 [d < 0.05].

    Args:
      pelvis_zz: [] pelvis xmat[2, 2]. robot_qvel: [nv_robot]. hand, goal: [3] left_hand site
        and goal positions; d = |hand - goal|.
    """
    dist = jnp.linalg.norm(hand - goal)
    healthy = 5.0 * pelvis_zz
    motion_penalty = jnp.sum(robot_qvel**2)
    close = jnp.where(dist < 1.0, 5.0, 0.0)
    success = jnp.where(dist < 0.05, 10.0, 0.0)
    reward = healthy - 1e-4 * motion_penalty + close + success
    terms = {
        "hand_dist": dist,
        "healthy_reward": healthy,
        "motion_penalty": motion_penalty,
        "reward_close": close,
        "reward_success": success,
    }
    return reward, terms


class WalkTask(Task):
    """Stand / walk / run on flat ground; terminates when the pelvis z < 0.2."""

    max_contact_points = LOCOMOTION_BUDGET

    def __init__(self, name: str, speed: float):
        self.name = name
        self.speed = float(speed)
        motion = "dont_move" if self.speed == 0 else "move"
        self.metric_names = ("standing", "upright", "small_control", motion)

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = walk_reward(
            robot.head_height(data),
            robot.torso_upright(data),
            robot.actuator_forces(data),
            robot.com_velocity(data),
            self.speed,
        )
        return reward, data.qpos[2] < 0.2, task_state, terms


class CrawlTask(Task):
    """Crawl through a 16 m tunnel (ceiling underside z 1.15, walls at y +-1.15); no termination."""

    max_contact_points = LOCOMOTION_BUDGET

    name = "crawl"
    metric_names = (
        "small_control", "move", "crawling", "crawling_head", "pelvis_quat", "in_tunnel",
    )  # fmt: skip

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        # Tunnel body at x 2.2 in HumanoidBench; its three boxes, in world coordinates.
        if self.contact_set == HB:  # HumanoidBench: the tunnel touches the whole robot
            bits = whole_robot_bits(spec, variant)
        else:  # the reduced set: feet and hands pass through the walls and ceiling
            bits = scene.set_contact_bits(spec, scene.robot_groups(variant),
                                          ("legs", "body", "arms"))  # fmt: skip
        for pos, size in (
            ((10.2, -1.35, 0.775), (8.0, 0.2, 0.775)),
            ((10.2, 1.35, 0.775), (8.0, 0.2, 0.775)),
            ((10.2, 0.0, 1.35), (8.0, 1.15, 0.2)),
        ):
            scene.add_static_geom(spec, bits, pos=pos, size=size, rgba=(0.5, 0.5, 0.5, 0.3))
        scene.set_max_geom_pairs(spec, 4)

    def bind(self, model, robot) -> None:
        self._pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = crawl_reward(
            robot.head_height(data),
            robot.site_pos(data, "imu"),
            data.xquat[self._pelvis],
            robot.actuator_forces(data),
            robot.com_velocity(data),
        )
        return reward, jnp.zeros((), bool), task_state, terms


class ReachTask(Task):
    """Reach a random goal with the left hand; the goal is the task state; no termination."""

    max_contact_points = LOCOMOTION_BUDGET

    reset_edits = True
    name = "reach"
    metric_names = (
        "hand_dist", "healthy_reward", "motion_penalty", "reward_close", "reward_success",
    )  # fmt: skip
    extra_obs_size = 6
    goal_low = (-2.0, -2.0, 0.2)
    goal_high = (2.0, 2.0, 2.0)

    def bind(self, model, robot) -> None:
        self._qvel = robot.qvel_slice

    def init(self, key, qpos):
        goal = jax.random.uniform(
            key, (3,), minval=jnp.array(self.goal_low), maxval=jnp.array(self.goal_high)
        )
        return qpos, goal

    def evaluate(self, robot, data: mjx.Data, goal):
        reward, terms = reach_reward(
            robot.pelvis_upright(data),
            data.qvel[self._qvel],
            robot.site_pos(data, "left_hand"),
            goal,
        )
        return reward, jnp.zeros((), bool), goal, terms

    def extra_obs(self, robot, data: mjx.Data, goal):
        return jnp.concatenate([robot.site_pos(data, "left_hand"), goal])

    def reset_ops(self) -> list[dict]:
        return [{"op": "value_uniform", "name": "goal", "low": list(self.goal_low),
                 "high": list(self.goal_high)}]  # fmt: skip

    def reset_state(self, values, qpos):
        return jnp.asarray(values["goal"], jnp.float32)

    def extra_obs_fields(self) -> list[dict]:
        return [{"name": "task/left_hand", "source": "site_xpos", "site": "left_hand", "size": 3},
                {"name": "task/goal", "source": "reset_value", "value": "goal", "size": 3}]
