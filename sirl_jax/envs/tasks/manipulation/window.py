"""Wipe a window with a long-handled wiper (HumanoidBench Window)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.overlap import PairQuery
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    body_id,
    geom_ids,
    hand_sites,
)

WINDOW_POS = (1.0, 0.0, 0.0)
TOOL_POS = (0.45, 0.0, 1.085)  # HumanoidBench's keyframe (the body's own pos is z 1.2)
TOOL_ROD = (0.02, 0.5)  # cylinder (radius, half length) along y at z 0.02
WIPER_POS = (0.0, 0.5, 0.02)  # the wiper head's body, on a ball joint (cone limit 1.4 rad)
WIPER_SPHERE, WIPER_BOX = 0.03, (0.1, 0.01, 0.05)  # the box at (0, 0.03, 0.02)
WIPER_LIMIT = 1.4
DENSITY = 1000.0  # the visual geoms' default: rod 1.257 kg, head 0.513 kg
WIPE_X, WIPE_MARGIN = 0.92, 0.4
TOOL_SPEED, TOOL_SPEED_MARGIN = 0.5, 0.5
HEAD_MOVE, HEAD_MOVE_MARGIN = 0.4, 0.1
HAND_BOUND, HAND_MARGIN = 0.2, 0.5
ROOT_TERMINATION, TOOL_TERMINATION = 0.58, 0.58
_WIPE_SITES = tuple(f"wipe_contact_site_{c}" for c in "abcde")
_WIPE_SITE_POS = ((0.1, 0.04, 0.07), (-0.1, 0.04, 0.07), (0.1, 0.04, -0.03), (-0.1, 0.04, -0.03),
                  (0.0, 0.04, 0.02))  # fmt: skip
# The frame (static): (pos, half size) of the base, the 4 lower and 4 upper columns, the middle
# and top bars; the pane's collider spans the whole window.
_FRAME = (
    ((0, 0, 0.35), (0.1, 1, 0.35)),
    *(((0, y, 1.1), (0.1, 0.025, 0.4)) for y in (-0.975, -0.325, 0.325, 0.975)),
    ((0, 0, 1.5125), (0.1, 1, 0.025)),
    *(((0, y, 1.7125), (0.1, 0.025, 0.2)) for y in (-0.975, -0.325, 0.325, 0.975)),
    ((0, 0, 1.915), (0.1, 1, 0.025)),
)  # fmt: skip
PANE = ((0, 0, 0.97), (0.05, 1, 0.97))


def window_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    head: jax.Array,
    head0: jax.Array,
    tool_vz: jax.Array,
    hands: jax.Array,
    tool: jax.Array,
    wipe_x: jax.Array,
    touching: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Window: 0.5 manipulation + 0.5 [wiper touches the pane] * wipe, with
    manipulation = 0.2 stand * small_control * head_move + 0.4 moving + 0.4 hand_proximity,
    head_move = tol(|head - head at reset|, (0.4, 0.4), margin 0.1),
    moving = tol(|tool subtree v_z|, (0.5, 0.5), margin 0.5),
    hand_proximity = min over hands of tol(|hand - tool|, (0, 0.2), margin 0.5) (the farther
    hand counts) and wipe = min over the 5 wiper sites of tol(x, (0.92, 0.92), margin 0.4, linear).

    Args:
      head, head0: [3] head site now and after reset. tool_vz: [] the tool subtree's vertical
      velocity. hands: [2, 3] left_hand, right_hand sites. tool: [3] the tool body.
      wipe_x: [5] x of the wiper sites. touching: [] bool, wiper box and pane overlap.
    """
    stand_reward = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    wipe = jnp.min(R.tolerance(wipe_x, (WIPE_X, WIPE_X), margin=WIPE_MARGIN, sigmoid="linear"))
    contact = touching.astype(jnp.float32)
    proximity = jnp.min(
        R.tolerance(jnp.linalg.norm(hands - tool, axis=-1), (0.0, HAND_BOUND), margin=HAND_MARGIN)
    )
    moving = R.tolerance(jnp.abs(tool_vz), (TOOL_SPEED, TOOL_SPEED), margin=TOOL_SPEED_MARGIN)
    head_move = R.tolerance(
        jnp.linalg.norm(head - head0), (HEAD_MOVE, HEAD_MOVE), margin=HEAD_MOVE_MARGIN
    )
    manipulation = (
        0.2 * (stand_reward * small_control * head_move) + 0.4 * moving + 0.4 * proximity
    )
    reward = 0.5 * manipulation + 0.5 * contact * wipe
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "moving_wipe_reward": moving,
        "hand_tool_proximity_reward": proximity,
        "window_contact_reward": wipe,
        "window_contact_filter": contact,
        "window_contact_total_reward": contact * wipe,
    }
    return reward, terms


class WindowTask(ManipulationTask):
    """A window frame (static) 1 m in front of the robot and a free 1 m wiping tool with a wiper
    head on a ball joint; the task state is the head site's position after reset. Terminates when
    the root or the tool drops below 0.58 m. Observation: full qpos and qvel (171).

    The tool-pane contact is an exact overlap test of the wiper box and the pane box (MuJoCo C
    finds a contact exactly when they overlap; margins are 0). HumanoidBench's keyframe gives the
    tool and the ball joint the quaternion (0, 0, 0, 0), so after reset noise both orientations
    are random (the normalised noise); hb_compat "exact" does the same, "fixed" starts both at
    (1, 0, 0, 0) + noise (this model's keyframe): the rod lies along y in front of the robot.
    Colliders: the rod is a capsule of the same length (MJX has no cylinder-box pair); the frame,
    pane, sphere and wiper are as in HumanoidBench. The tool touches the hands, the floor and the
    window; the robot's body passes through the window."""

    reset_edits = True
    object_qpos = (*TOOL_POS, 1, 0, 0, 0, 1, 0, 0, 0)  # the tool's free joint, the wiper's ball
    max_geom_pairs = 8
    name = "window"
    metric_names = (
        "stand_reward", "small_control", "moving_wipe_reward", "hand_tool_proximity_reward",
        "window_contact_reward", "window_contact_filter", "window_contact_total_reward",
    )  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        window = spec.worldbody.add_body(name="window", pos=WINDOW_POS)
        for pos, half in _FRAME:
            scene.add_fixture(spec, window, pos=pos, size=half, rgba=(0.55, 0.57, 0.6, 1))
        scene.add_fixture(spec, window, name="window_pane_collision", pos=PANE[0], size=PANE[1],
                          rgba=(0.2, 0.95, 0.95, 0.3))  # fmt: skip
        tool = spec.worldbody.add_body(name="window_wiping_tool", pos=TOOL_POS)
        tool.add_freejoint(name="free_window_wiping_tool")
        radius, half = TOOL_ROD
        scene.add_mass_geom(tool, DENSITY, type=scene.CYLINDER, size=(radius, half, 0),
                            pos=(0, 0, 0.02), quat=scene.Y_AXIS, rgba=(0.75, 0.75, 0.78, 1))
        scene.add_object_geom(tool, type=scene.CAPSULE, size=(radius, half - radius, 0),
                              pos=(0, 0, 0.02), quat=scene.Y_AXIS, density=0.0)  # fmt: skip
        wiper = tool.add_body(name="window_wiper_sphere", pos=WIPER_POS)
        wiper.add_joint(type=mujoco.mjtJoint.mjJNT_BALL, limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                        range=(0.0, WIPER_LIMIT))  # fmt: skip
        scene.add_object_geom(wiper, type=scene.SPHERE, size=(WIPER_SPHERE, 0, 0),
                              density=DENSITY, rgba=(0.75, 0.75, 0.78, 1))  # fmt: skip
        scene.add_object_geom(wiper, name="window_wipe_collision", type=scene.BOX,
                              size=WIPER_BOX, pos=(0, 0.03, 0.02), density=DENSITY,
                              rgba=(0.9, 0.9, 0.9, 1))  # fmt: skip
        for name, pos in zip(_WIPE_SITES, _WIPE_SITE_POS, strict=True):
            wiper.add_site(name=name, pos=pos)
        spec.add_sensor(name="window_wiping_tool_subtreelinvel",
                        type=mujoco.mjtSensor.mjSENS_SUBTREELINVEL,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname="window_wiping_tool")

    def bind(self, model, robot) -> None:
        self._tool = body_id(model, "window_wiping_tool")
        site = {model.site(i).name: i for i in range(model.nsite)}
        self._wipe_sites = jnp.array([site[n] for n in _WIPE_SITES])
        sensor = model.sensor("window_wiping_tool_subtreelinvel").id
        self._tool_vel_adr = int(model.sensor_adr[sensor])
        wipe, pane = geom_ids(model, ("window_wipe_collision", "window_pane_collision"))
        self._touch = PairQuery(model, [wipe], [pane])
        tool = int(model.jnt_qposadr[model.joint("free_window_wiping_tool").id]) + 3
        ball = int(model.jnt_qposadr[model.body_jntadr[body_id(model, "window_wiper_sphere")]])
        adr = [*range(tool, tool + 4), *range(ball, ball + 4)]
        self._quats = jnp.asarray(adr)
        self._key_quats = jnp.asarray(model.key_qpos[0][adr], jnp.float32)

    def init(self, key, qpos):
        if self.exact:  # HumanoidBench's zero quaternions: the reset noise alone
            qpos = qpos.at[self._quats].add(-self._key_quats)
        return qpos, jnp.zeros(3, jnp.float32)

    def after_reset(self, robot, data: mjx.Data, head0):
        return data, robot.site_pos(data, "head")

    def evaluate(self, robot, data: mjx.Data, head0):
        hands = hand_sites(robot, data)
        tool = data.xpos[self._tool]
        reward, terms = window_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            robot.site_pos(data, "head"), head0, data.sensordata[self._tool_vel_adr + 2], hands,
            tool, data.site_xpos[self._wipe_sites, 0], self._touch.any(data),
        )  # fmt: skip
        terminated = (data.qpos[2] < ROOT_TERMINATION) | (tool[2] < TOOL_TERMINATION)
        return reward, terminated, head0, terms
