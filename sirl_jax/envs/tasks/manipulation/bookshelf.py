"""Put five of twelve objects on a bookshelf in turn (HumanoidBench BookshelfSimple and
BookshelfHard)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.task_parts import budget_for
from sirl_jax.envs.tasks import props, scene
from sirl_jax.envs.tasks.manipulation.base import (
    ManipulationTask,
    body_id,
    hand_sites,
)

SHELF_POS = (0.95, 0.0, 0.0)
OBJECTS = ("book_a", "book_b", "book_c", "book_d", "book_e", "trophy", "book_flat", "soda_can",
           "book_thick", "chalk", "snow_globe", "headphone")  # fmt: skip
GOALS = ((0.75, -0.25, 1.55), (0.8, 0.05, 0.95), (0.8, -0.25, 0.95), (0.85, 0.05, 0.35),
         (0.85, -0.25, 0.35))  # fmt: skip
SIMPLE_ORDER = (5, 2, 9, 4, 1)  # trophy, book_c, chalk, book_e, book_b (HumanoidBench's -19, ...)
N_ITEMS = 5
PLACED, GOAL_MARGIN = 0.15, 1.0
BONUS = 100.0  # x k for the k-th placement
ROOT_TERMINATION, OBJECT_TERMINATION = 0.58, 0.5
# Keyframe (HumanoidBench's): position and quaternion of each object; its (0, 0, 0, 0) entries
# (no reset noise here) are the identity, which is what MuJoCo makes of them.
_POSES = {
    "book_a": (0.95, -0.36, 1.25), "book_b": (0.95, -0.3, 1.25), "book_c": (0.95, -0.24, 1.25),
    "book_d": (0.95, -0.18, 1.25), "book_e": (0.95, -0.12, 1.25), "trophy": (0.95, 0.02, 1.25),
    "book_flat": (0.95, 0.12, 1.255, 0.7073883, -0.7068252, 0, 0),
    "soda_can": (0.95, -0.3, 0.65), "book_thick": (0.95, -0.13, 0.65), "chalk": (0.95, 0, 0.65),
    "snow_globe": (0.95, 0.2, 0.65),
    "headphone": (0.85, 0, 1.58, 0.8689313, -0.06692531, 0.12250874, 0.47483787),
}  # fmt: skip
# Books: HumanoidBench's mass and inertia come from its book mesh (scaled 1.5 or 1.5 x 2.5 x
# 1.5 for the thick one); these are its compiled values (mass, diagonal inertia, ipos, iquat).
_BOOK = (2.266, (0.014335, 0.009709, 0.00555), (0.0009, 0.0024, 0.1151),
         (0.7085, -0.0032, -0.0035, 0.7057))  # fmt: skip
_BOOK_FLAT = (2.266, (0.014335, 0.009709, 0.00555), (0.0009, -0.0226, 0.1151), _BOOK[3])
_BOOK_THICK = (3.774, (0.023881, 0.017544, 0.010617), (0.0009, 0.0041, 0.1151),
               (0.71, -0.003, -0.0036, 0.7042))  # fmt: skip
_CHALK_AXIS = (math.cos(math.pi / 4), -0.5, 0.5, 0.0)  # the chalk's axis along (1, 1, 0)


def bookshelf_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    obj: jax.Array,
    goal: jax.Array,
    hands: jax.Array,
    index: jax.Array,
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Bookshelf: 0.2 stand * small_control + 0.4 tol(|obj - goal|, (0, 0.15),
    margin 1, linear) + 0.4 exp(-min over hands of |hand - obj|); the object within 0.15 of its
    goal moves the task to the next item and pays 100 x (the new item count).

    Args:
      obj: [3] the current object. goal: [3] its goal. hands: [2, 3]. index: [] int32 items
      placed so far.

    Returns:
      (reward [], new index [], terms).
    """
    stand_reward = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    dist = jnp.linalg.norm(obj - goal)
    proximity = R.tolerance(dist, (0.0, PLACED), margin=GOAL_MARGIN, sigmoid="linear")
    hand = jnp.exp(-jnp.min(jnp.linalg.norm(hands - obj, axis=-1)))
    reward = 0.2 * (stand_reward * small_control) + 0.4 * proximity + 0.4 * hand
    placed = dist < PLACED
    index = index + placed.astype(index.dtype)
    reward = reward + jnp.where(placed, BONUS * index, 0.0)
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "reward_proximity": proximity,
        "reward_hand_proximity": hand,
        "obj_goal_dist": dist,
        "success_subtasks": index.astype(jnp.float32),
        "success": (index >= N_ITEMS).astype(jnp.float32),
    }
    return reward, index, terms


class BookshelfTask(ManipulationTask):
    """Twelve free objects (books, a trophy, a can, chalk, a snow globe, headphones) on a shelf
    0.95 m ahead; five of them, one after another, go to five goals on other boards. Simple: a
    fixed list of objects and goals; hard: five distinct objects and the goal order drawn from
    the reset key. Terminates when the root or the current object drops below 0.58 / 0.5 m, or
    after the fifth placement. No reset noise (HumanoidBench's is 0 here). Observation: full
    qpos and qvel, then the current object as HumanoidBench encodes it (its body index counted
    from the end of HumanoidBench's body list, -24 ... -13), as of before the step (308).

    Task state: the object order and goals (one extra copy of the last, as HumanoidBench pads
    them), the items placed and the item the observation shows. HumanoidBench's goal markers
    (12 weld bodies it moves in `model.body_pos`) are not built: the goals are task state.
    Contacts: the objects touch the hands, the shelf and the floor, not each other (the books
    stand 1 cm apart). Colliders: HumanoidBench's boxes for the books; `props` for the rest
    (the can a box of its area, the chalk a capsule)."""

    metric_names = (
        "stand_reward", "small_control", "reward_proximity", "reward_hand_proximity",
        "obj_goal_dist", "success_subtasks", "success",
    )  # fmt: skip
    reset_noise = 0.0
    extra_obs_size = 1
    object_qpos = tuple(v for name in OBJECTS for v in (
        *_POSES[name], *(() if len(_POSES[name]) == 7 else (1.0, 0.0, 0.0, 0.0))))  # fmt: skip
    max_geom_pairs = 32
    max_contact_points = budget_for(104)  # its most active contacts (pair_cap)

    def __init__(self, name: str):
        if name not in ("bookshelf_simple", "bookshelf_hard"):
            raise ValueError(f"unknown bookshelf task {name!r}; allowed: "
                             f"'bookshelf_simple', 'bookshelf_hard'")  # fmt: skip
        self.name = name
        self.randomise = name == "bookshelf_hard"
        self.reset_edits = self.randomise  # bookshelf_hard draws the order and the goals

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        scene.add_shelf(spec, SHELF_POS)
        book = _book(_BOOK, (0.0025, 0, 0.115), (0.082, 0.025, 0.115))
        builders = {
            **{f"book_{c}": book for c in "abcde"},
            "trophy": props.trophy,
            "book_flat": _book(_BOOK_FLAT, (0, -0.022, 0.115), (0.082, 0.028, 0.115)),
            "soda_can": _soda_can,
            "book_thick": _book(_BOOK_THICK, (0.0025, 0.003, 0.115), (0.082, 0.0415, 0.115)),
            "chalk": lambda b: props.rod(b, (0, 0, 0.01), 0.01, 0.07, quat=_CHALK_AXIS),
            "snow_globe": props.snow_globe,
            "headphone": props.headphone,
        }  # fmt: skip
        for name in OBJECTS:
            body = spec.worldbody.add_body(name=name)
            body.add_freejoint(name=f"free_{name}")
            builders[name](body)

    def bind(self, model, robot) -> None:
        self._bodies = jnp.array([body_id(model, n) for n in OBJECTS])

    def init(self, key, qpos):
        order, goals = jnp.array(SIMPLE_ORDER), jnp.array(GOALS, jnp.float32)
        if self.randomise:
            k_order, k_goals = jax.random.split(key)
            order = jax.random.choice(k_order, len(OBJECTS), (N_ITEMS,), replace=False)
            goals = jax.random.permutation(k_goals, goals)
        state = {
            "order": jnp.concatenate([order, order[-1:]]).astype(jnp.int32),
            "goals": jnp.concatenate([goals, goals[-1:]]),
            "index": jnp.zeros((), jnp.int32),
            "shown": jnp.zeros((), jnp.int32),
        }
        return qpos, state

    def reset_ops(self) -> list[dict] | None:
        return None if self.randomise else []  # bookshelf_hard draws the order and the goals

    def evaluate(self, robot, data: mjx.Data, state):
        index = state["index"]
        obj = data.xpos[self._bodies[state["order"][index]]]
        hands = hand_sites(robot, data)
        reward, new_index, terms = bookshelf_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            obj, state["goals"][index], hands, index,
        )  # fmt: skip
        current_z = data.xpos[self._bodies[state["order"][new_index]], 2]
        terminated = (
            (data.qpos[2] < ROOT_TERMINATION) | (new_index >= N_ITEMS)
            | (current_z < OBJECT_TERMINATION)
        )  # fmt: skip
        return reward, terminated, {**state, "index": new_index, "shown": index}, terms

    def extra_obs(self, robot, data: mjx.Data, state):
        shown = state["order"][state["shown"]] - len(OBJECTS) * 2  # HumanoidBench: -24 ... -13
        return shown[None].astype(jnp.float32)


def _book(inertial, pos, half):
    mass, inertia, ipos, iquat = inertial

    def build(body: mujoco.MjsBody) -> None:
        scene.set_inertial(body, mass, inertia, ipos, iquat)
        scene.add_object_geom(body, type=scene.BOX, pos=pos, size=half, density=0.0,
                              rgba=(0.5, 0.3, 0.25, 1))  # fmt: skip

    return build


def _soda_can(body: mujoco.MjsBody) -> None:
    """1.57 kg: a cylinder r 0.05 x 0.2 m standing on its base; collider a box of its area."""
    scene.add_mass_geom(body, scene.DENSITY, type=scene.CYLINDER, pos=(0, 0, 0.1),
                        size=(0.05, 0.1, 0), rgba=(0.8, 0.1, 0.1, 1))  # fmt: skip
    side = 0.05 * math.sqrt(math.pi) / 2
    scene.add_object_geom(body, type=scene.BOX, pos=(0, 0, 0.1), size=(side, side, 0.1),
                          density=0.0)  # fmt: skip
