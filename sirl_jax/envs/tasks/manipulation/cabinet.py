"""Four sequential cabinet subtasks: slide a door, pull a drawer, move two cubes up a shelf
(HumanoidBench Cabinet)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.manipulation.base import ManipulationTask, body_id

CABINET_X = 0.9
CUBE_HALF, CUBE_MASS = 0.05, 1.0
CUBES = (
    ("drawer_cube", 0.58), ("lateral_cabinet_cube", 0.87), ("pulling_cabinet_cube", 1.16),
    ("pullup_drawer_cube", 1.45),
)  # fmt: skip
PANEL_MASS = 5.0  # HumanoidBench's moving panels carry mass="5"; the rest density 1000
PULL_RANGE, DRAWER_RANGE = 0.4, 0.45
OPEN = 0.95
SHELF_X, SHELF_Y, SHELF_Z = 0.3, 0.6, 0.15  # half extents of the "in the cabinet" box
SHELF_CENTRE_Z = (0.94, 1.54)  # subtask 3 (lateral cabinet), subtask 4 (pull-up drawer)
HORIZONTAL_MARGIN, VERTICAL_MARGIN = 0.3, 0.3
BONUS = 100.0  # x k on completing subtask k
N_SUBTASKS = 4

Box = tuple[tuple[float, float, float], tuple[float, float, float], float | None]
# (pos, half size, mass or None for density 1000) in the part's body frame.
_DRAWER: tuple[Box, ...] = (
    ((0, 0, 0.02), (0.3, 0.58, 0.01), PANEL_MASS),
    ((0.29, 0, 0.15), (0.01, 0.58, 0.14), PANEL_MASS),
    ((-0.29, 0, 0.15), (0.01, 0.58, 0.14), PANEL_MASS),
    ((0, 0.57, 0.15), (0.3, 0.01, 0.14), PANEL_MASS),
    ((0, -0.57, 0.15), (0.3, 0.01, 0.14), PANEL_MASS),
    ((-0.39, 0, 0.24), (0.01, 0.2, 0.01), None),
)
_DOOR_PANEL: Box = ((0, 0, 0.01), (0.01, 0.28, 0.13), PANEL_MASS)


def _door_handle(y: float) -> tuple[Box, ...]:
    return (((-0.1, y, 0), (0.01, 0.01, 0.09), None),)


def _door_posts(y: float) -> tuple[tuple[float, float, float], ...]:
    return ((-0.06, y, 0.09), (-0.06, y, -0.09))


def cabinet_subtask_reward(
    stage: jax.Array, q: jax.Array, drawer_cube: jax.Array, lateral_cube: jax.Array
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """The current subtask's reward (before the 0.2 / 0.8 mix) and whether it is complete.

    1. slide the pulling door: |q_pull / 0.4|, complete above 0.95;
    2. pull the drawer: |q_drawer / 0.45|, complete above 0.95;
    3. drawer cube into the lateral cabinet: 0.5 (0.3 horizontal + 0.7 vertical) + 0.5 max over
       its two doors of min(1, |q|), complete when the cube is inside x 0.9 +- 0.3, y +- 0.6,
       z 0.94 +- 0.15; horizontal = mean of tol(x - 0.9, (-0.3, 0.3), 0.3) and
       tol(y, (-0.6, 0.6), 0.3), vertical = tol(z - 0.94, (-0.15, 0.15), 0.3), all linear;
    4. lateral cube into the pull-up drawer: the same with z 1.54 and the pull-up door.

    Args:
      stage: [] int32 in 1..4. q: [5] cabinet joints in qpos order: drawer, left door, right
      door, pulling door, pull-up door. drawer_cube, lateral_cube: [3] the two cubes.

    Returns:
      (reward [], complete [] bool, terms).
    """
    pull = jnp.abs(q[3] / PULL_RANGE)
    drawer = jnp.abs(q[0] / DRAWER_RANGE)
    lateral_doors = jnp.maximum(jnp.minimum(1.0, jnp.abs(q[1])), jnp.minimum(1.0, jnp.abs(q[2])))
    pullup_door = jnp.minimum(1.0, jnp.abs(q[4]))

    def place(cube, centre_z, door):
        x, y, z = cube[0] - CABINET_X, cube[1], cube[2] - centre_z
        horizontal = (
            R.tolerance(x, (-SHELF_X, SHELF_X), margin=HORIZONTAL_MARGIN, sigmoid="linear")
            + R.tolerance(y, (-SHELF_Y, SHELF_Y), margin=HORIZONTAL_MARGIN, sigmoid="linear")
        ) / 2
        vertical = R.tolerance(z, (-SHELF_Z, SHELF_Z), margin=VERTICAL_MARGIN, sigmoid="linear")
        proximity = 0.3 * horizontal + 0.7 * vertical
        inside = (jnp.abs(x) <= SHELF_X) & (jnp.abs(y) <= SHELF_Y) & (jnp.abs(z) <= SHELF_Z)
        return 0.5 * proximity + 0.5 * door, inside, proximity

    r3, done3, prox3 = place(drawer_cube, SHELF_CENTRE_Z[0], lateral_doors)
    r4, done4, prox4 = place(lateral_cube, SHELF_CENTRE_Z[1], pullup_door)
    i = jnp.clip(stage - 1, 0, N_SUBTASKS - 1)
    reward = jnp.stack([pull, drawer, r3, r4])[i]
    complete = jnp.stack([pull > OPEN, drawer > OPEN, done3, done4])[i]
    door = jnp.stack([pull, drawer, lateral_doors, pullup_door])[i]
    proximity = jnp.stack([0.0, 0.0, prox3, prox4])[i]
    terms = {"door_openness_reward": door, "drawer_cube_proximity_reward": proximity}
    return reward, complete, terms


def cabinet_reward(
    head_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    stage: jax.Array,
    q: jax.Array,
    drawer_cube: jax.Array,
    lateral_cube: jax.Array,
) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Cabinet: 0.2 stand * small_control + 0.8 subtask reward, plus 100 k in the
    step that completes subtask k, which also advances the stage; completing subtask 4 ends
    the episode (stage 5). Returns (reward, new stage, terms)."""
    stand_reward = R.standing(head_z) * R.upright(zz, 0.9)
    small_control = R.small_control(force)
    sub, complete, terms = cabinet_subtask_reward(stage, q, drawer_cube, lateral_cube)
    reward = 0.2 * stand_reward * small_control + 0.8 * sub
    reward = reward + jnp.where(complete, BONUS * stage, 0.0)
    stage = stage + complete.astype(stage.dtype)
    terms = {
        "stand_reward": stand_reward,
        "small_control": small_control,
        "success_subtasks": (stage - 1).astype(jnp.float32),
        "success": (stage > N_SUBTASKS).astype(jnp.float32),
        "subtask_complete": complete.astype(jnp.float32),
        **terms,
    }
    return reward, stage, terms


class CabinetTask(ManipulationTask):
    """A cabinet 0.9 m ahead, four compartments from the bottom: a drawer (slide, damping 80),
    a shelf behind two hinged doors, a shelf behind a sliding door (damping 50), and a shelf
    behind a pull-up door; a 10 cm, 1 kg cube in each. The task state is the current subtask
    (1-4; 5 = done, which terminates). Observation: full qpos and qvel (213).

    Contacts: the moving parts (drawer, doors, handles) touch the hands and the cubes; the static
    shelves and panels touch the cubes; the robot's body passes through the cabinet (the
    profile). Handle cylinders are capsules of the same length (MJX has no cylinder-box pair);
    masses are HumanoidBench's (its moving panels 5 kg each, the rest density 1000)."""

    # the five hinges and slides closed, then the cubes
    object_qpos = (0.0,) * 5 + tuple(
        v for _, z in CUBES for v in (CABINET_X, 0.0, z, 1.0, 0.0, 0.0, 0.0))
    max_geom_pairs = 12
    name = "cabinet"
    metric_names = (
        "stand_reward", "small_control", "success_subtasks", "success", "subtask_complete",
        "door_openness_reward", "drawer_cube_proximity_reward",
    )  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        x = CABINET_X
        world = spec.worldbody
        for pos, half in (((x, 0, 0.25), (0.3, 0.6, 0.25)), ((1.21, 0, 0.84), (0.009, 0.6, 0.84)),
                          ((x, 0.59, 0.84), (0.3, 0.01, 0.84)),
                          ((x, -0.59, 0.84), (0.3, 0.01, 0.84))):  # fmt: skip
            scene.add_fixture(spec, world, pos=pos, size=half, rgba=_WOOD)
        drawer = world.add_body(name="drawer", pos=(x, 0, 0.5))
        drawer.add_joint(name="drawer_slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=(-1, 0, 0),
                         range=(0, DRAWER_RANGE), limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                         damping=80.0)  # fmt: skip
        _moving_part(drawer, _DRAWER, ((-0.35, -0.2, 0.24), (-0.35, 0.2, 0.24)))

        lateral = world.add_body(name="lateral_cabinet", pos=(x, 0, 0.79))
        _shelf(spec, lateral)
        for side, y, lo_hi in (("left", 0.29, (-1.57, 0.0)), ("right", -0.29, (0.0, 1.57))):
            door = lateral.add_body(name=f"{side}_door", pos=(-0.29, y, 0.15))
            door.add_joint(name=f"{side}_door_hinge", pos=(0, y, 0.15), axis=(0, 0, 1),
                           range=lo_hi, limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=1.0)
            _moving_part(door, (_DOOR_PANEL, *_door_handle(-0.2 * y / 0.29)),
                         _door_posts(-0.2 * y / 0.29))  # fmt: skip

        pulling = world.add_body(name="pulling_cabinet", pos=(x, 0, 1.08))
        _shelf(spec, pulling)
        scene.add_fixture(spec, pulling, pos=(-0.29, -0.29, 0.16), size=(0.01, 0.28, 0.13),
                          rgba=_WOOD)  # fmt: skip
        door = pulling.add_body(name="pulling_door", pos=(-0.32, 0.29, 0.15))
        door.add_joint(name="pull_door_slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=(0, 1, 0),
                       range=(-PULL_RANGE, 0), limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                       damping=50.0)  # fmt: skip
        _moving_part(door, (_DOOR_PANEL, *_door_handle(0.2)), _door_posts(0.2))

        pullup = world.add_body(name="pullup_drawer", pos=(x, 0, 1.37))
        _shelf(spec, pullup)
        scene.add_fixture(spec, pullup, pos=(0.01, 0, 0.3), size=(0.29, 0.6, 0.01), rgba=_WOOD)
        door = pullup.add_body(name="pullup_door")
        door.add_joint(name="pullup_door_hinge", pos=(-0.29, 0, 0.29), axis=(0, 1, 0),
                       range=(0, 1.57), limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=10.0)
        _moving_part(door, (((-0.29, 0, 0.16), (0.01, 0.58, 0.125), PANEL_MASS),
                            ((-0.39, 0, 0.08), (0.01, 0.2, 0.01), None)),
                     ((-0.35, -0.2, 0.08), (-0.35, 0.2, 0.08)))  # fmt: skip

        for name, z in CUBES:
            cube = world.add_body(name=name, pos=(x, 0, z))
            cube.add_freejoint(name=f"free_{name}")
            scene.add_object_geom(cube, type=scene.BOX, size=(CUBE_HALF,) * 3,
                                  mass=CUBE_MASS, rgba=(0.85, 0.3, 0.2, 1))  # fmt: skip

    def bind(self, model, robot) -> None:
        joints = ("drawer_slide", "left_door_hinge", "right_door_hinge", "pull_door_slide",
                  "pullup_door_hinge")  # fmt: skip
        self._q = jnp.array([int(model.jnt_qposadr[model.joint(j).id]) for j in joints])
        self._drawer_cube = body_id(model, "drawer_cube")
        self._lateral_cube = body_id(model, "lateral_cabinet_cube")

    def init(self, key, qpos):
        return qpos, jnp.ones((), jnp.int32)

    def reset_ops(self) -> list[dict]:
        return []  # init only starts the task state; the key is unused

    def evaluate(self, robot, data: mjx.Data, stage):
        reward, stage, terms = cabinet_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            stage, data.qpos[self._q], data.xpos[self._drawer_cube],
            data.xpos[self._lateral_cube],
        )  # fmt: skip
        return reward, stage > N_SUBTASKS, stage, terms


_WOOD = (0.55, 0.4, 0.28, 1)


def _shelf(spec: mujoco.MjSpec, body: mujoco.MjsBody) -> None:
    """A compartment's static floor and back panel."""
    scene.add_fixture(spec, body, pos=(0, 0, 0.02), size=(0.3, 0.6, 0.01), rgba=_WOOD)
    scene.add_fixture(spec, body, pos=(0.29, 0, 0.15), size=(0.01, 0.6, 0.14), rgba=_WOOD)


def _moving_part(body: mujoco.MjsBody, boxes: tuple[Box, ...], posts) -> None:
    """Boxes and handle posts (cylinders r 0.02, 0.1 m along x: capsules here, their mass from
    the cylinder) of a drawer or door: they touch the hands and the cubes."""
    contype = scene.HANDS | scene.FIXTURE  # the hands' conaffinity, and the cubes'
    for pos, half, mass in boxes:
        inertia = {"mass": mass} if mass is not None else {"density": 1000.0}
        body.add_geom(type=scene.BOX, pos=pos, size=half, contype=contype, conaffinity=0,
                      group=3, rgba=_WOOD, **inertia)  # fmt: skip
    for pos in posts:
        scene.add_mass_geom(body, 1000.0, type=scene.CYLINDER, pos=pos, size=(0.02, 0.05, 0),
                            quat=scene.X_AXIS, rgba=(0.1, 0.1, 0.1, 1))  # fmt: skip
        body.add_geom(type=scene.CAPSULE, pos=pos, size=(0.02, 0.03, 0), quat=scene.X_AXIS,
                      contype=contype, conaffinity=0, group=3, density=0.0)  # fmt: skip
