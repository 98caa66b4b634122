"""Stir a cup with a spoon: follow a circling target inside it (HumanoidBench Spoon)."""

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
    geom_ids,
    hand_sites,
)

TABLE_POS = (1.0, 0.0, 0.45)
TABLE_TOP = (0.5, 0.5, 0.05)  # half size at z + 0.4: top surface at z 0.9
CUP_POS = (0.75, -0.1, 0.9)
SPOON_POS = (0.75, 0.2, 0.9)
HANDLE = (0.007, 0.08)  # cylinder (radius, half length) along x at z 0.0035
PLATE = (0.03, 0.005, 0.1)  # cylinder (radius, half height, x offset)
DENSITY = 1000.0  # the visual geoms' default: the spoon weighs 0.053 kg
TARGET_CENTRE = (0.75, -0.1, 0.95)
TARGET_RADIUS, TARGET_PERIOD = 0.06, 40  # control steps per revolution
SPIN_MARGIN, HAND_BOUND, HAND_MARGIN = 0.15, 0.2, 0.5
IN_CUP, IN_CUP_Z = 0.1, 0.1  # |plate - cup| < 0.1 per axis, z measured from cup z + 0.1
ROOT_TERMINATION = 0.58
# The cup (static): (pos, half size) of its walls, bottom and the handle's two bars.
_CUP_BOXES = (
    ((0, 0.1, 0.1), (0.12, 0.02, 0.1)), ((0, -0.1, 0.1), (0.12, 0.02, 0.1)),
    ((-0.1, 0, 0.1), (0.02, 0.12, 0.1)), ((0.1, 0, 0.1), (0.02, 0.12, 0.1)),
    ((0, 0, 0.01), (0.12, 0.12, 0.02)),
    ((0, 0.15, 0.14), (0.01, 0.05, 0.01)), ((0, 0.15, 0.02), (0.01, 0.05, 0.01)),
)  # fmt: skip


def spoon_target(step: jax.Array) -> jax.Array:
    """[3] the target at control step `step`: centre + 0.06 (cos, sin, 0) of step * 2 pi / 40."""
    angle = jnp.asarray(step, jnp.float32) * (2.0 * jnp.pi / TARGET_PERIOD)
    offset = TARGET_RADIUS * jnp.stack([jnp.cos(angle), jnp.sin(angle), jnp.zeros_like(angle)])
    return jnp.asarray(TARGET_CENTRE, jnp.float32) + offset


def spoon_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    hands: jax.Array,
    handle: jax.Array,
    plate: jax.Array,
    cup: jax.Array,
    target: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Spoon: 0.15 stand * small_control + 0.25 hand_proximity + 0.25 in_cup
    + 0.35 spinning, with hand_proximity = tol(min over hands of |hand - handle|, (0, 0.2),
    margin 0.5), in_cup = [|plate - cup| < 0.1 in x and y, and |plate z - (cup z + 0.1)| < 0.1]
    and spinning = tol(|plate - target|, margin 0.15).

    Args:
      hands: [2, 3] left_hand, right_hand sites. handle, plate: [3] the spoon's handle and plate
      centres. cup: [3] the cup body. target: [3] `spoon_target` of this step.
    """
    stand_reward = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    hand_dist = jnp.min(jnp.linalg.norm(hands - handle, axis=-1))
    proximity = R.tolerance(hand_dist, (0.0, HAND_BOUND), margin=HAND_MARGIN)
    offset = plate - cup - jnp.array([0.0, 0.0, IN_CUP_Z])
    in_cup = jnp.all(jnp.abs(offset) < IN_CUP).astype(jnp.float32)
    spinning = R.tolerance(jnp.linalg.norm(plate - target), margin=SPIN_MARGIN)
    reward = (
        0.15 * (stand_reward * small_control) + 0.25 * proximity + 0.25 * in_cup + 0.35 * spinning
    )
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "hand_tool_proximity_reward": proximity,
        "reward_spoon_in_cup": in_cup,
        "spoon_spinning_reward": spinning,
    }
    return reward, terms


class SpoonTask(ManipulationTask):
    """A free spoon on a table next to a fixed cup; stir along a target that circles inside the
    cup (radius 0.06 m, one turn per 40 control steps). The task state is HumanoidBench's step
    counter (mod 40: "phase") and the phase the observation shows ("shown"): a step's reward
    uses the target of the phase, then advances it, and the observation after the step shows
    the target its reward used (HumanoidBench computes the observation before it advances its
    counter, so the reset observation and the first step's show the same phase).
    HumanoidBench never resets its counter: hb_compat "exact" carries the phase over to the
    next episode of the same env; "fixed" starts every episode at phase 0. Observation: full
    qpos and qvel, then the target (167).

    Colliders (MJX has no cylinder-box pair, and the palms, table and cup are boxes): the handle
    is a capsule of the same length, the plate a box of the same area and thickness; the mass and
    inertia come from HumanoidBench's cylinders (non-colliding geoms)."""

    object_qpos = (*SPOON_POS, 1, 0, 0, 0)
    max_geom_pairs = 8
    max_contact_points = budget_for(49)  # its most active contacts (pair_cap)
    name = "spoon"
    metric_names = (
        "stand_reward", "small_control", "hand_tool_proximity_reward", "reward_spoon_in_cup",
        "spoon_spinning_reward",
    )  # fmt: skip
    extra_obs_size = 3

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        scene.add_table(spec, TABLE_POS, TABLE_TOP, leg_xy=(0.4, 0.4))
        cup = spec.worldbody.add_body(name="cup", pos=CUP_POS)
        for pos, half in _CUP_BOXES:
            scene.add_fixture(spec, cup, pos=pos, size=half, rgba=(0.6, 0.6, 0.62, 1))
        scene.add_fixture(spec, cup, type=scene.CAPSULE, pos=(0, 0.19, 0.08), size=(0.01, 0.05, 0),
                          rgba=(0.6, 0.6, 0.62, 1))  # fmt: skip
        spoon = spec.worldbody.add_body(name="spoon", pos=SPOON_POS)
        spoon.add_freejoint(name="free_spoon")
        radius, half = HANDLE
        p_radius, p_half, p_x = PLATE
        steel = (0.75, 0.75, 0.78, 1)
        scene.add_mass_geom(spoon, DENSITY, name="spoon_handle", type=scene.CYLINDER,
                            size=(radius, half, 0), pos=(0, 0, 0.0035), quat=scene.X_AXIS,
                            rgba=steel)  # fmt: skip
        scene.add_mass_geom(spoon, DENSITY, name="spoon_plate", type=scene.CYLINDER,
                            size=(p_radius, p_half, 0), pos=(p_x, 0, 0.0035), rgba=steel)
        scene.add_object_geom(spoon, type=scene.CAPSULE, size=(radius, half - radius, 0),
                              pos=(0, 0, 0.0035), quat=scene.X_AXIS, density=0.0)  # fmt: skip
        side = p_radius * math.sqrt(math.pi) / 2  # a square of the disc's area
        scene.add_object_geom(spoon, type=scene.BOX, size=(side, side, p_half),
                              pos=(p_x, 0, 0.0035), density=0.0)  # fmt: skip

    def bind(self, model, robot) -> None:
        self._handle, self._plate = geom_ids(model, ("spoon_handle", "spoon_plate"))
        self._cup = body_id(model, "cup")

    def init(self, key, qpos):
        zero = jnp.zeros((), jnp.int32)
        return qpos, {"phase": zero, "shown": zero}

    def carry(self, previous, fresh):
        if not self.exact:
            return fresh
        return {"phase": previous["phase"], "shown": previous["phase"]}

    def reset_ops(self) -> list[dict]:
        return []  # init only starts the task state; the key is unused

    def evaluate(self, robot, data: mjx.Data, state):
        hands = hand_sites(robot, data)
        phase = state["phase"]
        reward, terms = spoon_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            hands, data.geom_xpos[self._handle], data.geom_xpos[self._plate],
            data.xpos[self._cup], spoon_target(phase),
        )  # fmt: skip
        state = {"phase": (phase + 1) % TARGET_PERIOD, "shown": phase}
        return reward, data.qpos[2] < ROOT_TERMINATION, state, terms

    def extra_obs(self, robot, data: mjx.Data, state):
        return spoon_target(state["shown"])
