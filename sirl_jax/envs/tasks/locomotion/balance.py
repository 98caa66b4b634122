"""Balance on a board lying on a sphere, fixed (balance_simple) or free (balance_hard)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.humanoid import Task
from sirl_jax.envs.overlap import PairQuery, below_floor
from sirl_jax.envs.task_parts import LOCOMOTION_BUDGET, contact_arrays, fallen, geom_mask
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.locomotion.obstacles import whole_robot_bits
from sirl_jax.hb_compat import HB

BALANCE_ROOT = (-0.1, 0.0, 1.38)
BOARD_Z, BOARD_HALF = 0.37, (0.15, 0.55, 0.03)
PIVOT_Z, PIVOT_RADIUS = 0.17, 0.17


def balance_reward(
    head_z: jax.Array, zz: jax.Array, force: jax.Array, v_com: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Balance: small_control * tol(head_z, (2.02, inf), 0.4125) * upright(0.9)
    * dont_move (standing height 1.65 + 0.37, margin 1.65 / 4)."""
    standing = R.tolerance(head_z, (R.STAND_HEIGHT + 0.37, math.inf), margin=R.STAND_HEIGHT / 4)
    upright = R.upright(zz, 0.9)
    small_control = R.small_control(force)
    dont_move = R.dont_move(v_com[:2])
    reward = small_control * standing * upright * dont_move
    terms = {
        "standing": standing,
        "upright": upright,
        "small_control": small_control,
        "dont_move": dont_move,
    }
    return reward, terms


class BalanceTask(Task):
    """Stand on the board. Terminates when the root z < 0.8, when the sphere touches anything but
    the floor or the board, or when the floor touches anything but the sphere.

    Args:
      contact_rule: "query" (default): the sphere and floor rules test every robot geom, hands
        included, exactly (`overlap`), plus the board against the floor; "contacts": MJX's
        contact slots, where only the feet and legs can touch the sphere and the hands never
        touch the floor.
    """

    max_contact_points = LOCOMOTION_BUDGET

    metric_names = ("standing", "upright", "small_control", "dont_move")

    def __init__(self, name: str, contact_rule: str = "query"):
        if name not in ("balance_simple", "balance_hard"):
            raise ValueError(
                f"unknown balance task {name!r}; allowed: 'balance_simple', 'balance_hard'"
            )
        if contact_rule not in ("query", "contacts"):
            raise ValueError(f"contact_rule={contact_rule!r}; allowed: ('query', 'contacts')")
        self.name = name
        self.free_pivot = name == "balance_hard"
        self.contact_rule = contact_rule

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        if self.contact_set == HB:  # HumanoidBench: board and sphere touch the whole robot
            standing_on = everything = whole_robot_bits(spec, variant)
        else:  # the reduced set: the board carries the feet; only the feet and legs reach the
            # sphere before the root drops below 0.8 m (itself a termination)
            groups = scene.robot_groups(variant)
            standing_on = scene.set_contact_bits(spec, groups, ("feet",))
            everything = scene.set_contact_bits(spec, groups, ("feet", "legs"))
        board = spec.worldbody.add_body(name="stand_board", pos=(0, 0, BOARD_Z))
        board.add_freejoint(name="free_stand_board")
        # Board: the robot, the floor (contype 1) and the pivot (scene.OBJECT).
        board.add_geom(
            name="stand_board_collision",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=BOARD_HALF,
            contype=standing_on,
            conaffinity=1 | scene.OBJECT,
            rgba=(0.7, 0.7, 0.7, 1),
        )
        pivot = spec.worldbody.add_body(name="rolling_pivot", pos=(0, 0, PIVOT_Z))
        if self.free_pivot:
            pivot.add_freejoint(name="free_rolling_pivot")
        pivot.add_geom(
            name="pivot_sphere_collision",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=(PIVOT_RADIUS, 0, 0),
            contype=everything | scene.OBJECT,
            conaffinity=1,
            rgba=(0.3, 0.3, 0.3, 1),
        )
        key = spec.keys[0]
        qpos = list(key.qpos)
        qpos[0:3] = BALANCE_ROOT
        key.qpos = qpos  # object entries are filled from their bodies' positions at compile

    def bind(self, model, robot) -> None:
        def gid(name):
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)

        floor, board = gid("floor"), gid("stand_board_collision")
        sphere = gid("pivot_sphere_collision")
        self._sphere = jnp.asarray(geom_mask(model, [sphere]))
        self._not_sphere = ~self._sphere
        self._floor = jnp.asarray(geom_mask(model, [floor]))
        self._not_floor_board = ~jnp.asarray(geom_mask(model, [floor, board]))
        robot_ids = np.concatenate(list(robot.geom_ids.values()))
        self._robot_names = [model.geom(int(g)).name for g in robot_ids]
        self._model = model
        self._robot_sphere = PairQuery(model, robot_ids, [sphere])
        self._on_floor = np.concatenate([robot_ids, [board]])

    @property
    def reads_contact_slots(self) -> bool:
        return self.contact_rule == "contacts"

    def _bad_contact(self, data: mjx.Data) -> jax.Array:
        if self.contact_rule == "query":
            return self._robot_sphere.any(data) | below_floor(self._model, self._on_floor, data)
        dist, geom = contact_arrays(data)
        sphere_bad = R.any_contact(dist, geom, self._sphere, self._not_floor_board)
        return sphere_bad | R.any_contact(dist, geom, self._floor, self._not_sphere)

    def termination_rule(self) -> dict | None:
        if self.contact_rule != "query":
            return None  # MJX's contact slots: not a rule another simulator can follow
        robot = self._robot_names
        return {"kind": "any", "rule": "root z < 0.8, or a bad sphere/floor contact", "rules": [
            {"kind": "qpos_below", "adr": 2, "value": 0.8},
            {"kind": "geoms_overlap", "a": robot, "b": ["pivot_sphere_collision"],
             "why": "a robot geom inside the sphere"},
            {"kind": "geoms_overlap", "a": [*robot, "stand_board_collision"], "b": ["floor"],
             "why": "a robot geom or the board below the floor plane"},
        ]}  # fmt: skip

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = balance_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            robot.com_velocity(data),
        )  # fmt: skip
        return reward, fallen(data.qpos[2], 0.8) | self._bad_contact(data), task_state, terms
