"""Unload five packages from a truck onto a table (HumanoidBench Truck)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.task_parts import budget_for
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import ManipulationTask, body_id, with_robot_entries

ROBOT_X = 2.0  # HumanoidBench's keyframe puts the robot at x 2
TRUCK_POS = (8.0, 0.0, 0.0)
TABLE_POS = (2.0, -1.7, 0.45)
PACKAGES = ("package_a", "package_b", "package_c", "package_d", "package_e")
# (half size, keyframe qpos) of each package: two stacks of two and one standing, on the bed.
_PACKAGES = (
    ((0.2, 0.1, 0.15), (5, 0, 1.1, 0.707105, -0.707108, 0, 0)),
    ((0.25, 0.2, 0.1), (5.1, 0, 1.3, 0.706752, 0, 0, 0.707462)),
    ((0.2, 0.3, 0.1), (5, 0.35, 1.3, 0.707105, 0.707108, 0, 0)),
    ((0.25, 0.3, 0.1), (5, -0.5, 1.1, 1, 0, 0, 0)),
    ((0.2, 0.2, 0.2), (5.1, -0.6, 1.4, 1, 0, 0, 0)),
)  # fmt: skip
DENSITY = 1000.0  # 24, 40, 48, 60 and 64 kg
ON_TRUCK, PICKED_UP, ON_TABLE = 0, 1, 2
LIFT = 0.1  # picked up: z above its z after the first step + 0.1
TABLE_X, TABLE_Y, TABLE_Z = (1.65, 2.35), (-2.05, -1.35), 0.5  # "upon the table": open bounds
EVENT, SUCCESS_BONUS = 100.0, 1000.0
DIST_BOUND, DIST_MARGIN = 0.2, 4.0
SEGMENT = 2.0  # m: the truck's long boxes are cut into pieces MJX's broad phase can rank
# Static truck boxes in the truck body's frame (pos, half size): the bed (its collider fills
# the wheels' height), the two side walls, the front wall, the roof, the wall of packages
# behind the load (one collider) and the ramp (pitched -0.5 rad about y).
_TRUCK = (
    ((0, 0, 0.5), (4, 1.2, 0.5)), ((0, 1.15, 2), (4, 0.05, 1)), ((0, -1.15, 2), (4, 0.05, 1)),
    ((4, 0, 2), (0.05, 1.2, 1)), ((0, 0, 3.05), (4, 1.2, 0.05)), ((-1, 0, 1.9), (0.2, 1.1, 0.9)),
)  # fmt: skip
_RAMP = ((-4.7, 0, 0.5), (0.85, 1.2, 0.1), (math.cos(-0.25), 0, math.sin(-0.25), 0))


def _upon_table(p: jax.Array) -> jax.Array:
    """[...] bool, a package xpos [..., 3] is over the table top and above z 0.5."""
    return ((p[..., 0] > TABLE_X[0]) & (p[..., 0] < TABLE_X[1]) & (p[..., 1] > TABLE_Y[0])
            & (p[..., 1] < TABLE_Y[1]) & (p[..., 2] > TABLE_Z))  # fmt: skip


def _nearest(d: jax.Array, mask: jax.Array) -> jax.Array:
    """tol(min of d over mask, (0, 0.2), margin 4, linear, 0 at the margin); 0 if mask is empty."""
    value = R.tolerance(jnp.min(jnp.where(mask, d, jnp.inf)), (0.0, DIST_BOUND),
                        margin=DIST_MARGIN, sigmoid="linear", value_at_margin=0.0)  # fmt: skip
    return jnp.where(mask.any(), value, 0.0)


def list_removals(
    member: jax.Array, order: jax.Array, cond: jax.Array, exact: bool
) -> tuple[jax.Array, jax.Array]:
    """Which members of a package list HumanoidBench's `for p in lst: if cond(p): ...
    lst.remove(p)` takes out, and the order they leave in.

    exact: the list is the members sorted by `order`; removing the package under the iterator
    shifts the next one into its place, so the loop skips it (HumanoidBench's quirk). Not
    exact: every member meeting `cond` leaves.

    Args:
      member: [5] bool, in the list. order: [5] int32 list positions (smaller first).
      cond: [5] bool.

    Returns:
      (removed [5] bool, rank [5] int32: how many removed packages left before each).
    """
    idx = jnp.argsort(jnp.where(member, order, jnp.iinfo(jnp.int32).max))
    removed = jnp.zeros(member.shape, bool)
    rank = jnp.zeros(member.shape, jnp.int32)
    count, skip = jnp.zeros((), jnp.int32), jnp.zeros((), bool)
    for i in range(member.shape[0]):
        p = idx[i]
        hit = member[p] & cond[p] & ~skip
        removed, rank = removed.at[p].set(hit), rank.at[p].set(count)
        count, skip = count + hit, hit if exact else skip
    return removed, rank


def _move(lists: dict, src: int, dst: int, cond: jax.Array, exact: bool):
    """`lists` with the packages of list `src` that `cond` takes out appended to list `dst`."""
    status, order, joins = lists["status"], lists["order"], lists["joins"]
    removed, rank = list_removals(status == src, order, cond, exact)
    moved = jnp.sum(removed).astype(jnp.int32)
    lists = {"status": jnp.where(removed, dst, status),
             "order": jnp.where(removed, joins + rank, order), "joins": joins + moved}  # fmt: skip
    return lists, moved


def truck_lists() -> dict[str, jax.Array]:
    """HumanoidBench's three package lists at its start: all five on the truck, in order.
    {"status": [5] int32 (ON_TRUCK, PICKED_UP, ON_TABLE), "order": [5] int32 the position in
    its list, "joins": [] int32 the next position}."""
    n = len(PACKAGES)
    return {"status": jnp.full((n,), ON_TRUCK, jnp.int32), "order": jnp.arange(n, dtype=jnp.int32),
            "joins": jnp.asarray(n, jnp.int32)}  # fmt: skip


def truck_reward(
    zz: jax.Array,
    root: jax.Array,
    table: jax.Array,
    packages: jax.Array,
    lists: dict[str, jax.Array],
    z0: jax.Array,
    exact: bool = False,
) -> tuple[jax.Array, dict[str, jax.Array], dict[str, jax.Array]]:
    """HumanoidBench Truck: events, then upright-weighted distance terms.

    Events, in HumanoidBench's order within a step: a package on the truck whose z rises 0.1
    above its first-step z is picked up (+100); a picked-up package upon the table is placed
    (+100); a placed package no longer upon the table is picked up again (-100). Then
    upright * (1 + near(root, packages on the truck) + near(root, picked-up packages)
    + near(table, picked-up packages)), near = tol(min distance, (0, 0.2), margin 4, linear),
    0 for an empty set; + 1000 (and the episode ends) when all five are placed. exact: each of
    the three event loops skips the package after one it moves (`list_removals`).

    Args:
      zz: [] torso zz. root: [3] the robot's free-joint position. table: [3] the table body.
      packages: [5, 3] package xpos. lists: `truck_lists` state. z0: [5] the packages' z
      after the first step.

    Returns:
      (reward [], new lists, terms).
    """
    on_table = _upon_table(packages)
    lists, lifted = _move(lists, ON_TRUCK, PICKED_UP, packages[:, 2] > z0 + LIFT, exact)
    lists, placed = _move(lists, PICKED_UP, ON_TABLE, on_table, exact)
    lists, dropped = _move(lists, ON_TABLE, PICKED_UP, ~on_table, exact)
    status = lists["status"]
    events = EVENT * (lifted + placed - dropped).astype(jnp.float32)
    upright = R.upright(zz, 0.9)
    to_root = jnp.linalg.norm(packages - root, axis=-1)
    to_table = jnp.linalg.norm(packages - table, axis=-1)
    near_truck = _nearest(to_root, status == ON_TRUCK)
    near_picked = _nearest(to_root, status == PICKED_UP)
    near_table = _nearest(to_table, status == PICKED_UP)
    success = jnp.all(status == ON_TABLE)
    reward = events + upright * (1.0 + near_truck + near_picked + near_table)
    reward = reward + jnp.where(success, SUCCESS_BONUS, 0.0)
    count = lambda s: jnp.sum(status == s).astype(jnp.float32)  # noqa: E731
    terms = {
        "upright": upright,
        "reward_robot_package_truck": near_truck,
        "reward_robot_package_picked_up": near_picked,
        "reward_package_table": near_table,
        "packages_on_truck": count(ON_TRUCK),
        "packages_picked_up": count(PICKED_UP),
        "packages_on_table": count(ON_TABLE),
        "success_subtasks": count(ON_TABLE),
        "success": success.astype(jnp.float32),
    }
    return reward, lists, terms


class TruckTask(ManipulationTask):
    """A truck (static, its bed 1 m high, a ramp up to it) 4-12 m ahead with five heavy free
    packages (24-64 kg) on its bed, and a table at (2, -1.7); the robot starts at x 2. The task
    state is HumanoidBench's three package lists (`truck_lists`) and each package's z after the
    first step. hb_compat "exact": the lists and heights carry over to the next episode of the
    same env (HumanoidBench never resets them) and each event loop skips the package after one
    it moves; "fixed": they start afresh each episode and every package is tested every step.
    Terminates when all five are on the table. Observation: full qpos and qvel (216).

    Contacts: the truck (bed, ramp, walls, roof, the wall of packages) touches the robot's body,
    legs and arms (the robot walks up the ramp) and the packages; the packages touch the hands,
    the truck, the table, the floor and each other (they start stacked)."""

    robot_qpos = with_robot_entries({0: ROBOT_X})
    object_qpos = tuple(v for _, q in _PACKAGES for v in q)
    max_geom_pairs = 48  # the stacked packages: docs/tasks.md, "Contact budget"
    max_contact_points = budget_for(92)  # its most active contacts (pair_cap)
    name = "truck"
    metric_names = (
        "upright", "reward_robot_package_truck", "reward_robot_package_picked_up",
        "reward_package_table", "packages_on_truck", "packages_picked_up", "packages_on_table",
        "success_subtasks", "success",
    )  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        truck = spec.worldbody.add_body(name="truck", pos=TRUCK_POS)
        for k, (pos, half) in enumerate(_TRUCK):  # the robot's body, legs, arms; the packages
            scene.add_segmented_box(truck, f"truck_{k}", pos, half, SEGMENT, contype=scene.FLOOR,
                                    conaffinity=0, rgba=_GREY)  # fmt: skip
        pos, half, quat = _RAMP
        truck.add_geom(name="slide_collision", type=scene.BOX, pos=pos, size=half, quat=quat,
                       contype=scene.FLOOR, conaffinity=0, group=3, rgba=_GREY)  # fmt: skip
        scene.add_table(spec, TABLE_POS, (0.5, 0.5, 0.05), top_z=0.45, leg_xy=(0.4, 0.4),
                        leg_z=0.0, leg_half_z=0.5)  # fmt: skip
        for name, (half, _) in zip(PACKAGES, _PACKAGES, strict=True):
            body = spec.worldbody.add_body(name=name)
            body.add_freejoint(name=f"free_{name}")
            scene.add_object_geom(body, touch_objects=True, type=scene.BOX, size=half,
                                  density=DENSITY, rgba=(0.75, 0.6, 0.4, 1))  # fmt: skip

    def bind(self, model, robot) -> None:
        self._packages = jnp.array([body_id(model, n) for n in PACKAGES])
        self._table = body_id(model, "table")

    def init(self, key, qpos):
        return qpos, {**truck_lists(), "z0": jnp.full((len(PACKAGES),), jnp.nan, jnp.float32)}

    def carry(self, previous, fresh):
        return previous if self.exact else fresh

    def reset_ops(self) -> list[dict]:
        return []  # init only starts the task state; the key is unused

    def evaluate(self, robot, data: mjx.Data, state):
        packages = data.xpos[self._packages]
        z0 = jnp.where(jnp.isnan(state["z0"]), packages[:, 2], state["z0"])
        lists = {k: state[k] for k in ("status", "order", "joins")}
        reward, lists, terms = truck_reward(
            robot.torso_upright(data), data.qpos[:3], data.xpos[self._table], packages, lists,
            z0, self.exact,
        )  # fmt: skip
        done = jnp.all(lists["status"] == ON_TABLE)
        return reward, done, {**lists, "z0": z0}, terms


_GREY = (0.5, 0.5, 0.5, 1)
