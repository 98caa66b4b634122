"""Insert the two ends of a block into two pegs on a table (HumanoidBench InsertNormal and
InsertSmall)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.task_parts import budget_for
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import ManipulationTask, hand_sites

TABLE_POS = (0.9, 0.0, 0.45)
TABLE_TOP = (0.5, 0.5, 0.05)  # half size at z + 0.45: top surface at z 0.95
PEG_POS = {"a": (0.8, -0.2, 0.95), "b": (0.8, 0.2, 0.95)}
BLOCK_POS = (0.6, 0.0, 0.95)
DENSITY = 1000.0  # the visual geoms' default; pegs 0.448 / 0.048 kg, block 0.389 / 0.077 kg
PEG_HEIGHT, PEG_HEIGHT_MARGIN = 1.1, 0.15
TARGET_MARGIN, HAND_BOUND, HAND_MARGIN = 0.5, 0.2, 0.5
ROOT_TERMINATION, OBJECT_TERMINATION = 0.5, 0.5
_PEGS = ("a", "b")


@dataclasses.dataclass(frozen=True)
class InsertSize:
    """One peg: a square base plate and four walls around a square cup, and the block's
    cross-section (HumanoidBench insert_normal.xml / insert_small.xml)."""

    base: float  # the base plate's half side (its half thickness is 0.005)
    wall: float  # a wall's half thickness
    wall_half_z: float
    site_z: tuple[float, float]  # peg_a's and peg_b's site heights above the body origin
    block: float  # the block's half width and half height (its half length is 0.15)

    def peg_boxes(self) -> list[tuple[tuple[float, float, float], tuple[float, float, float]]]:
        """(pos, half size) of the base and the four walls (the walls start 1 cm up)."""
        c, h, t, z = self.base - self.wall, self.base, self.wall, 0.01 + self.wall_half_z
        return [
            ((0.0, 0.0, 0.005), (h, h, 0.005)),
            ((0.0, -c, z), (h, t, self.wall_half_z)),
            ((0.0, c, z), (h, t, self.wall_half_z)),
            ((-c, 0.0, z), (t, h, self.wall_half_z)),
            ((c, 0.0, z), (t, h, self.wall_half_z)),
        ]


SIZES = {
    "insert_normal": InsertSize(base=0.04, wall=0.01, wall_half_z=0.03, site_z=(0.01, 0.01),
                                block=0.018),
    # HumanoidBench's insert_small.xml puts peg_a's site at z 0.005 and peg_b's at z 0.01.
    "insert_small": InsertSize(base=0.02, wall=0.005, wall_half_z=0.01, site_z=(0.005, 0.01),
                               block=0.008),
}  # fmt: skip


def insert_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    block_ends: jax.Array,
    pegs: jax.Array,
    hands: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Insert:
    (0.5 small_control * stand + 0.5 target) * (0.5 peg_height + 0.5 hand_proximity), with
    target = mean over pegs a, b of tol(|block_peg_x - peg_x|, margin 0.5, linear),
    peg_height = mean of tol(peg z - 1.1, margin 0.15, linear) and
    hand_proximity = tol(min(|left_hand - peg_a|, |right_hand - peg_b|), (0, 0.2), margin 0.5).

    Args:
      block_ends: [2, 3] sites block_peg_a, block_peg_b. pegs: [2, 3] sites peg_a, peg_b.
      hands: [2, 3] left_hand, right_hand sites.
    """
    stand_reward = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    target = jnp.mean(
        R.tolerance(jnp.linalg.norm(block_ends - pegs, axis=-1), margin=TARGET_MARGIN,
                    sigmoid="linear")  # fmt: skip
    )
    peg_height = jnp.mean(
        R.tolerance(pegs[:, 2] - PEG_HEIGHT, margin=PEG_HEIGHT_MARGIN, sigmoid="linear")
    )
    hand_dist = jnp.min(jnp.linalg.norm(hands - pegs, axis=-1))
    proximity = R.tolerance(hand_dist, (0.0, HAND_BOUND), margin=HAND_MARGIN)
    reward = (0.5 * (small_control * stand_reward) + 0.5 * target) * (
        0.5 * peg_height + 0.5 * proximity
    )
    terms = {
        "small_control": small_control,
        "stand_reward": stand_reward,
        "cube_target_reward": target,
        "hand_tool_proximity_reward": proximity,
        "peg_height_reward": peg_height,
    }
    return reward, terms


def insert_terminated(root_z: jax.Array, sites_z: jax.Array) -> jax.Array:
    """root z < 0.5, or any of the four peg and block-end sites below z 0.5. sites_z: [4]."""
    return (root_z < ROOT_TERMINATION) | jnp.any(sites_z < OBJECT_TERMINATION)


class InsertTask(ManipulationTask):
    """Two free pegs (square cups) and a free block on a table; lift the pegs to 1.1 m and put the
    block's ends (sites block_peg_a/b) into them. Every collider is a box, as in HumanoidBench;
    the pegs and the block touch each other (and the hands, table and floor). Observation: full
    qpos and qvel (190)."""

    object_qpos = tuple(v for p in (PEG_POS["a"], PEG_POS["b"], BLOCK_POS)
                        for v in (*p, 1, 0, 0, 0))  # fmt: skip
    max_geom_pairs = 12
    max_contact_points = budget_for(47)  # its most active contacts (pair_cap)
    metric_names = (
        "small_control", "stand_reward", "cube_target_reward", "hand_tool_proximity_reward",
        "peg_height_reward",
    )  # fmt: skip

    def __init__(self, name: str):
        if name not in SIZES:
            raise ValueError(f"unknown insert task {name!r}; allowed: {sorted(SIZES)}")
        self.name = name
        self.size = SIZES[name]

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        scene.add_table(spec, TABLE_POS, TABLE_TOP, top_z=0.45, leg_xy=(0.4, 0.4), leg_z=0.0,
                        leg_half_z=0.5)  # fmt: skip
        shades = {"a": (0.2, 0.2, 0.2, 1), "b": (0.8, 0.8, 0.8, 1)}
        for ch, site_z in zip(_PEGS, self.size.site_z, strict=True):
            peg = spec.worldbody.add_body(name=f"peg_{ch}", pos=PEG_POS[ch])
            peg.add_freejoint(name=f"free_peg_{ch}")
            peg.add_site(name=f"peg_{ch}", pos=(0, 0, site_z))
            for pos, half in self.size.peg_boxes():
                scene.add_object_geom(peg, touch_objects=True, type=scene.BOX, pos=pos, size=half,
                                      density=DENSITY, rgba=shades[ch])  # fmt: skip
        s = self.size.block
        block = spec.worldbody.add_body(name="block_a", pos=BLOCK_POS)
        block.add_freejoint(name="free_block_a")
        block.add_site(name="block_peg_b", pos=(0, -0.15, s))
        block.add_site(name="block_peg_a", pos=(0, 0.15, s))
        scene.add_object_geom(block, touch_objects=True, type=scene.BOX, pos=(0, 0, s),
                              size=(s, 0.15, s), density=DENSITY,
                              rgba=(0.65, 0.65, 0.65, 1))  # fmt: skip

    def bind(self, model, robot) -> None:
        site = {model.site(i).name: i for i in range(model.nsite)}
        self._pegs = jnp.array([site[f"peg_{ch}"] for ch in _PEGS])
        self._ends = jnp.array([site[f"block_peg_{ch}"] for ch in _PEGS])

    def evaluate(self, robot, data: mjx.Data, task_state):
        pegs, ends = data.site_xpos[self._pegs], data.site_xpos[self._ends]
        hands = hand_sites(robot, data)
        reward, terms = insert_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            ends, pegs, hands,
        )  # fmt: skip
        sites_z = jnp.concatenate([ends[:, 2], pegs[:, 2]])
        return reward, insert_terminated(data.qpos[2], sites_z), task_state, terms
