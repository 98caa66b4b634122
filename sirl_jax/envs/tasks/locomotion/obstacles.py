"""Tasks with obstacles whose touch costs reward: hurdle, maze, pole (HumanoidBench §3).

Every robot collider, hands included, collides with the obstacles, as in HumanoidBench; the
hands still do not touch the floor. `max_geom_pairs` lets MJX evaluate only the nearest
candidate pairs of each collision function, so long walls are built from short segments: MJX
ranks candidates by bounding spheres, and one 70 m wall would rank first whatever its distance.

The 0.1 discount fires when any robot geom touches a penalised obstacle. `contact_rule="query"`
(the default) asks `overlap.PairQuery` (an exact test of every robot-obstacle pair, once per
control step); `"contacts"` scans MJX's contact slots instead, which miss what `max_geom_pairs`
pruned and MJX's capsule-box edge misses (docs/tasks.md, contact parity).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs import h1
from sirl_jax.envs import rewards as R
from sirl_jax.envs.humanoid import Task
from sirl_jax.envs.overlap import PairQuery
from sirl_jax.envs.task_parts import LOCOMOTION_BUDGET, contact_arrays, fallen, geom_mask
from sirl_jax.envs.tasks import scene

WALL_DISCOUNT = 0.1
"""Reward factor while touching a barrier / maze block / pole."""
OBSTACLE_GROUPS = ("feet", "legs", "body", "arms", "hands", "links")
"""The robot groups that collide with the obstacles, and with stair's treads and slide's ramps
(all of them; the hands through their wrist and palm boxes, `obstacle_colliders`)."""
CONTACT_RULES = ("query", "contacts")


def obstacle_colliders(variant: str) -> dict[str, tuple[str, ...]]:
    """The robot colliders that collide with obstacles, by group: every body, arm and leg
    collider, and of each hand only the wrist and palm colliders (8 of 31,
    `h1.HAND_FLOOR_GEOMS["palms"]`). MJX's broad phase
    scores every candidate pair on every substep: with all 62 hand geoms and 1-2 m wall
    segments hurdle had 13,663 pairs and ran at 0.35 of the bare robot's rate; palms only and
    2.5-5 m segments give 2,159. The penalty still tests every finger (`PairQuery` over all
    robot geoms); only the physics lets a finger pass into an obstacle."""
    groups = dict(scene.robot_groups(variant))
    if "hands" in groups:
        groups["hands"] = h1.HAND_FLOOR_GEOMS["palms"]
    return groups


def whole_robot_bits(spec: mujoco.MjSpec, variant: str) -> int:
    """The contype of a scene geom that touches every collider the obstacle tasks use
    (`OBSTACLE_GROUPS` over `obstacle_colliders`): HumanoidBench's scene geoms touch the whole
    robot. Sets the groups' bits on the robot's colliders."""
    return scene.set_contact_bits(spec, obstacle_colliders(variant), OBSTACLE_GROUPS)


def _obstacle_box(spec: mujoco.MjSpec, contype: int, name: str, pos, half, segment: float,
                  rgba) -> list[str]:  # fmt: skip
    """A penalised static box cut along its longest axis (`scene.add_segmented_box`), drawn by
    itself (group 0) and touching the robot parts whose bits are in `contype`."""
    return scene.add_segmented_box(spec.worldbody, name, pos, half, segment, along="longest",
                                   group=0, contype=contype, conaffinity=0, rgba=rgba)  # fmt: skip

def hurdle_reward(
    head_z: jax.Array, zz: jax.Array, force: jax.Array, v_com: jax.Array, touching: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Hurdle: small_control * standing * upright(0.8) * move(5) * wall.

    Args:
      touching: [] bool, an active contact involves a side or back barrier (wall = 0.1).
    """
    standing = R.standing(head_z)
    upright = R.upright(zz, 0.8)
    small_control = R.small_control(force)
    move = R.move(v_com[0], R.RUN_SPEED)
    wall = jnp.where(touching, WALL_DISCOUNT, 1.0)
    reward = small_control * standing * upright * move * wall
    terms = {
        "standing": standing,
        "upright": upright,
        "small_control": small_control,
        "move": move,
        "wall_collision_discount": wall,
    }
    return reward, terms


MAZE_CHECKPOINTS = ((0.0, 0.0), (3.0, 0.0), (3.0, 6.0), (6.0, 6.0), (6.0, 6.0))
# Move direction in each stage (after reaching checkpoint stage-1): +x, +x, +y, +x, +y.
MAZE_DIRECTIONS = ((1.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 0.0), (0.0, 1.0))
MAZE_SPEED = 2.0
MAZE_RADIUS = 0.4


def maze_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    v_com: jax.Array,
    pelvis_xy: jax.Array,
    imu_xy: jax.Array,
    touching: jax.Array,
    stage: jax.Array,
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Maze: (0.2 stand*control + 0.4 move + 0.4 prox) * wall + stage bonus.

    The stage advances (at most to 4) when the pelvis xy is within 0.4 of the current
    checkpoint, paying 100 * new_stage; move and prox then use the new stage.

    Args:
      pelvis_xy, imu_xy: [2]. touching: [] bool, an active contact involves a maze block.
      stage: [] int32 current stage (0..4).

    Returns:
      (reward [], new stage [] int32, terms).
    """
    checkpoints = jnp.asarray(MAZE_CHECKPOINTS, jnp.float32)
    directions = jnp.asarray(MAZE_DIRECTIONS, jnp.float32)
    last = len(MAZE_CHECKPOINTS) - 1
    reached = jnp.linalg.norm(pelvis_xy - checkpoints[stage]) < MAZE_RADIUS
    new_stage = jnp.where(reached, jnp.minimum(stage + 1, last), stage).astype(jnp.int32)
    bonus = jnp.where(new_stage > stage, 100.0 * new_stage, 0.0)
    stand = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    direction = directions[new_stage]
    m = R.tolerance(
        v_com[0] - MAZE_SPEED * direction[0], margin=1.0, sigmoid="linear", value_at_margin=0.0
    ) * R.tolerance(
        v_com[1] - MAZE_SPEED * direction[1], margin=1.0, sigmoid="linear", value_at_margin=0.0
    )
    m = jnp.where(new_stage == last, 1.0, m)
    move = (5.0 * m + 1.0) / 6.0
    prox = R.tolerance(jnp.linalg.norm(checkpoints[new_stage] - imu_xy), margin=1.0)
    wall = jnp.where(touching, WALL_DISCOUNT, 1.0)
    reward = (0.2 * stand * small_control + 0.4 * move + 0.4 * prox) * wall + bonus
    terms = {
        "stand_reward": stand,
        "small_control": small_control,
        "move": move,
        "checkpoint_proximity_reward": prox,
        "wall_collision_discount": wall,
        "stage_convert_reward": bonus,
        "stage": new_stage.astype(jnp.float32),
    }
    return reward, new_stage, terms


def pole_reward(
    head_z: jax.Array, zz: jax.Array, force: jax.Array, v_com: jax.Array, touching: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Pole: (0.5 small_control * stand_reward + 0.5 move(0.5)) * coll.

    Args:
      touching: [] bool, an active contact involves a pole (coll = 0.1).
    """
    stand = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    move = R.move(v_com[0], 0.5)
    coll = jnp.where(touching, WALL_DISCOUNT, 1.0)
    reward = (0.5 * small_control * stand + 0.5 * move) * coll
    terms = {
        "stand_reward": stand,
        "small_control": small_control,
        "move": move,
        "collision_discount": coll,
    }
    return reward, terms


class _ContactTask(Task):
    """A task whose reward is discounted while any robot geom touches a penalised obstacle.

    Args:
      contact_rule: "query" (exact test of every robot-obstacle pair) or "contacts" (MJX's
        contact slots).
    """

    max_contact_points = LOCOMOTION_BUDGET

    _penalised_names: tuple[str, ...] = ()

    def __init__(self, contact_rule: str = "query"):
        if contact_rule not in CONTACT_RULES:
            raise ValueError(f"contact_rule={contact_rule!r}; allowed: {CONTACT_RULES}")
        self.contact_rule = contact_rule

    def bind(self, model, robot) -> None:
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in self._penalised_names]
        self._penalised = jnp.asarray(geom_mask(model, ids))
        robot_ids = np.concatenate(list(robot.geom_ids.values()))
        self._query = PairQuery(model, robot_ids, ids)

    @property
    def reads_contact_slots(self) -> bool:
        return self.contact_rule == "contacts"

    def _touching(self, data: mjx.Data) -> jax.Array:
        if self.contact_rule == "query":
            return self._query.any(data)
        return R.any_contact(*contact_arrays(data), self._penalised)


class HurdleTask(_ContactTask):
    """Run at 5 m/s over 10 hurdles (x = 7, 14, ..., 70; 0.375 m tall) in a 9 m wide lane."""

    name = "hurdle"
    metric_names = ("standing", "upright", "small_control", "move", "wall_collision_discount")

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        bits = whole_robot_bits(spec, variant)
        for k in range(1, 11):
            _obstacle_box(spec, bits, f"hurdle_{k}", (7.0 * k, 0, 0.1875), (0.03, 5, 0.1875), 2.5,
                          rgba=(0.9, 0.9, 0.9, 1))  # fmt: skip
        walls = (
            ("left_barrier_collision", (35.0, -4.725, 1.0), (35.5, 0.275, 1.0), 5.0),
            ("right_barrier_collision", (35.0, 4.725, 1.0), (35.5, 0.275, 1.0), 5.0),
            ("behind_barrier_collision", (-0.525, 0.0, 1.0), (0.05, 5.0, 1.0), 2.5),
        )
        names = []
        for name, pos, size, segment in walls:
            names += _obstacle_box(spec, bits, name, pos, size, segment, rgba=(0.1, 0.1, 0.1, 0.1))
        self._penalised_names = tuple(names)
        scene.set_max_geom_pairs(spec, 6)

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = hurdle_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            robot.com_velocity(data), self._touching(data),
        )  # fmt: skip
        return reward, fallen(data.qpos[2], 0.2), task_state, terms


# HumanoidBench's generated 7x7 maze, row r from the top (+y), column c from the left (-x):
# "#" holds a 1.5 x 1.5 x 1.2 m block (30 blocks). The robot starts in row 5, column 1.
_MAZE_MAP = (
    "#######",
    "#.....#",
    "###.#.#",
    "#.....#",
    "#.#.###",
    "#.....#",
    "#######",
)


def maze_block_centres() -> list[tuple[int, int, float, float]]:
    """(row, col, x, y) of the maze blocks; the grid's corner is at (-2.25, -2.25)."""
    out = []
    for r, row in enumerate(_MAZE_MAP):
        for c, cell in enumerate(row):
            if cell == "#":
                out.append((r, c, -2.25 + 0.75 + 1.5 * c, -2.25 + 9.75 - 1.5 * r))
    return out


class MazeTask(_ContactTask):
    """Walk through a 7x7 block maze via checkpoints (3,0), (3,6), (6,6); the stage is the task
    state."""

    name = "maze"
    metric_names = (
        "stand_reward", "small_control", "move", "checkpoint_proximity_reward",
        "wall_collision_discount", "stage_convert_reward", "stage",
    )  # fmt: skip

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        bits = whole_robot_bits(spec, variant)
        names = []
        for r, c, x, y in maze_block_centres():
            names.append(f"block_collision_{r}{c}")
            scene.add_static_geom(
                spec,
                bits,
                pos=(x, y, 0.6),
                size=(0.75, 0.75, 0.6),
                name=names[-1],
                rgba=(0.4, 0.4, 0.4, 0.3),
            )
        self._penalised_names = tuple(names)
        scene.set_max_geom_pairs(spec, 6)

    def init(self, key, qpos):
        return qpos, jnp.zeros((), jnp.int32)

    def reset_ops(self) -> list[dict]:
        return []  # init only starts the stage at 0

    def evaluate(self, robot, data: mjx.Data, stage):
        reward, stage, terms = maze_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            robot.com_velocity(data), data.xpos[self._pelvis, :2], robot.site_pos(data, "imu")[:2],
            self._touching(data), stage,
        )  # fmt: skip
        return reward, fallen(data.qpos[2], 0.2), stage, terms

    def bind(self, model, robot) -> None:
        super().bind(model, robot)
        self._pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")


def pole_positions() -> np.ndarray:
    """[P, 2] xy of HumanoidBench's poles: rows x = 1..41; odd rows y = +-0.75, +-2.25 (4 poles),
    even rows y = 0, +-1.5 (3 poles); 144 poles."""
    out = []
    for row in range(1, 42):
        ys = (2.25, 0.75, -0.75, -2.25) if row % 2 else (1.5, 0.0, -1.5)
        out += [(float(row), y) for y in ys]
    return np.asarray(out, np.float32)


class PoleTask(_ContactTask):
    """Walk at 0.5 m/s through a forest of 2 m poles (capsules r 0.05) between side barriers."""

    name = "pole"
    metric_names = ("stand_reward", "small_control", "move", "collision_discount")

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        bits = whole_robot_bits(spec, variant)
        names = []
        for k, (x, y) in enumerate(pole_positions()):
            names.append(f"pole_r{int(x)}_c{k}")
            # HumanoidBench: cylinder r 0.05, z 0..2; MJX has no cylinder-box/mesh collision.
            scene.add_static_geom(
                spec,
                bits,
                mujoco.mjtGeom.mjGEOM_CAPSULE,
                name=names[-1],
                fromto=(x, y, 0.05, x, y, 1.95),
                size=(0.05, 0, 0),
                rgba=(0.5, 0.5, 0.5, 1),
            )
        self._penalised_names = tuple(names)
        for name, pos, size in (
            ("pole_wall_left", (20.0, -3.15, 1.0), (20.75, 0.15, 1.0)),
            ("pole_wall_right", (20.0, 3.15, 1.0), (20.75, 0.15, 1.0)),
            ("pole_wall_behind", (-0.6, 0.0, 1.0), (0.15, 3.0, 1.0)),
        ):
            _obstacle_box(spec, bits, name, pos, size, 5.0, rgba=(0.9, 0.9, 0.9, 0.2))
        scene.set_max_geom_pairs(spec, 6)

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = pole_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            robot.com_velocity(data), self._touching(data),
        )  # fmt: skip
        return reward, fallen(data.qpos[2], 0.5), task_state, terms
