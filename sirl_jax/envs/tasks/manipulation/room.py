"""Tidy a walled room: gather six scattered objects (HumanoidBench Room)."""

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
    free_joint_adr,
)

OBJECTS = ("chair", "trophy", "headphone", "package_a", "package_b", "snow_globe")
# Reset: object k's x ~ U(-2.5 + k, -1.5 + k), y ~ +-U(1.2, 3.5) (a random side); z and the
# orientation are the keyframe's (HumanoidBench's body orientations, see RoomTask).
X_LOW, Y_RANGE = -2.5, (1.2, 3.5)
SPREAD_MARGIN = 3.0
ROOT_TERMINATION = 0.3
_HEADPHONE_QUAT = (0.0733422, 0.0519076, -0.240058, -0.966591)  # HumanoidBench's reset value
# Object keyframe poses: (z, quaternion). HumanoidBench's keyframe gives all but the headphone
# the quaternion (0, 0, 0, 0); these are the orientations of its <body> elements.
_POSES = {
    "chair": (0.0, (1, 0, 0, 0)),
    "trophy": (0.0, (1, 0, 0, 0)),
    "headphone": (0.0, _HEADPHONE_QUAT),
    "package_a": (0.1, (math.cos(-math.pi / 4), math.sin(-math.pi / 4), 0, 0)),  # euler x -pi/2
    "package_b": (0.1, (math.cos(0.7859), 0, 0, math.sin(0.7859))),  # euler z 1.5718
    "snow_globe": (0.0, (1, 0, 0, 0)),
}
_WALLS = (((-4.15, 0, 1.5), (0.15, 4, 1.5)), ((4.15, 0, 1.5), (0.15, 4, 1.5)),
          ((0, 3.85, 1.5), (4, 0.15, 1.5)), ((0, -3.85, 1.5), (4, 0.15, 1.5)))  # fmt: skip
WALL_SEGMENT = 2.0


def room_reward(
    head_z: jax.Array, zz: jax.Array, force: jax.Array, objects: jax.Array
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Room: 0.2 small_control * stand + 0.8 tol(max(var x, var y), margin 3)
    over the six objects' body positions (population variance, gaussian tolerance).

    Args:
      objects: [6, 3] the objects' xpos.
    """
    standing = R.standing(head_z)
    upright = R.upright(zz, 0.9)
    small_control = R.small_control(force)
    spread = jnp.max(jnp.var(objects[:, :2], axis=0))
    organized = R.tolerance(spread, margin=SPREAD_MARGIN)
    reward = 0.2 * (small_control * standing * upright) + 0.8 * organized
    terms = {
        "stand_reward": standing * upright,
        "small_control": small_control,
        "standing": standing,
        "upright": upright,
        "room_object_organized": organized,
    }
    return reward, terms


class RoomTask(ManipulationTask):
    """A walled 8 x 8 m room with a table and a shelf (static) and six free objects scattered at
    reset to either side of the robot; reward for gathering them. Terminates when the root drops
    below 0.3 m. Observation: full qpos and qvel (229).

    HumanoidBench's quirks (hb_compat "exact" reproduces them, "fixed" does not): its reset
    loop places seven "objects" for the scene's six, so the first write lands on the robot's
    qpos[nq - 49] and qpos[nq - 48] (the right hand's LFJ2 and LFJ1), set to U(-3.5, -2.5) and
    +-U(1.2, 3.5); its keyframe gives every object but the headphone the quaternion
    (0, 0, 0, 0), so they start in the random orientation of the reset noise, and it writes the
    headphone's quaternion after the noise. "fixed": the orientations of HumanoidBench's
    `<body>` elements (the headphone's given one) + noise, and the robot untouched.

    Contacts: the objects touch the hands, the floor, the walls, the table and the shelf (not
    each other); the walls also touch the robot's body, legs and arms (HumanoidBench collides
    everything). Object colliders: `props` (cylinders as boxes and capsules, HumanoidBench's
    masses)."""

    reset_edits = True
    object_qpos = tuple(v for n in OBJECTS for v in (0.0, 0.0, _POSES[n][0], *_POSES[n][1]))
    max_geom_pairs = 8
    max_contact_points = budget_for(50)  # its most active contacts (pair_cap)
    name = "room"
    metric_names = ("stand_reward", "small_control", "standing", "upright",
                    "room_object_organized")  # fmt: skip

    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        for k, (pos, half) in enumerate(_WALLS):  # the robot's body, legs, arms; the objects
            scene.add_segmented_box(spec.worldbody, f"wall_{k}", pos, half, WALL_SEGMENT,
                                    contype=scene.FLOOR, conaffinity=0, rgba=(0.7, 0.7, 0.7, 0.4))
        scene.add_table(spec, (2.7, -0.5, 0.45), (0.5, 0.5, 0.05), top_z=0.45, leg_xy=(0.4, 0.4),
                        leg_z=0.0, leg_half_z=0.5)  # fmt: skip
        scene.add_shelf(spec, (2.7, 0.5, 0.0))
        for name in OBJECTS:
            body = spec.worldbody.add_body(name=name)
            body.add_freejoint(name=f"free_{name}")
            _OBJECT_BUILDERS[name](body)

    def bind(self, model, robot) -> None:
        self._bodies = jnp.array([body_id(model, n) for n in OBJECTS])
        adr = [free_joint_adr(model, f"free_{n}")[0] for n in OBJECTS]
        self._adr = jnp.array(adr)
        self._stray = model.nq - 7 * (len(OBJECTS) + 1)  # HumanoidBench's seventh "object"
        quats = [a + 3 + k for a, n in zip(adr, OBJECTS, strict=True) if n != "headphone"
                 for k in range(4)]  # fmt: skip
        self._quats = jnp.asarray(quats)
        self._key_quats = jnp.asarray(model.key_qpos[0][quats], jnp.float32)
        self._headphone = adr[OBJECTS.index("headphone")] + 3

    def init(self, key, qpos):
        k_x, k_y, k_side = jax.random.split(key, 3)
        n = len(OBJECTS)
        x = X_LOW + jnp.arange(n) + jax.random.uniform(k_x, (n,))
        side = jnp.where(jax.random.bernoulli(k_side, 0.5, (n,)), 1.0, -1.0)
        y = side * jax.random.uniform(k_y, (n,), minval=Y_RANGE[0], maxval=Y_RANGE[1])
        qpos = qpos.at[self._adr].set(x).at[self._adr + 1].set(y)
        if self.exact:
            qpos = self._humanoidbench_writes(jax.random.fold_in(key, n), qpos)
        return qpos, ()

    def _humanoidbench_writes(self, key: jax.Array, qpos: jax.Array) -> jax.Array:
        """HumanoidBench's reset quirks: the stray "object" written into the right hand's
        fingers, zero quaternions (the noise alone), the headphone's quaternion without noise."""
        k_x, k_y, k_side = jax.random.split(key, 3)
        x = X_LOW - 1.0 + jax.random.uniform(k_x, ())
        side = jnp.where(jax.random.bernoulli(k_side, 0.5), 1.0, -1.0)
        y = side * jax.random.uniform(k_y, (), minval=Y_RANGE[0], maxval=Y_RANGE[1])
        qpos = qpos.at[self._stray].set(x).at[self._stray + 1].set(y)
        qpos = qpos.at[self._quats].add(-self._key_quats)
        head = jnp.asarray(_HEADPHONE_QUAT, qpos.dtype)
        return qpos.at[self._headphone : self._headphone + 4].set(head)

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = room_reward(
            robot.head_height(data), robot.torso_upright(data), robot.actuator_forces(data),
            data.xpos[self._bodies],
        )  # fmt: skip
        return reward, data.qpos[2] < ROOT_TERMINATION, task_state, terms


def _chair(body) -> None:
    """15.7 kg: mass from four legs, the seat, two back posts and the back rest; colliders:
    HumanoidBench's two boxes (the seat with its legs, and the back)."""
    legs = [((x, y, 0.225), (0.02, 0.02, 0.225)) for x in (0.19, -0.19) for y in (0.19, -0.19)]
    parts = [*legs, ((0, 0, 0.45), (0.21, 0.21, 0.025)),
             ((-0.23, 0.19, 0.6375), (0.02, 0.02, 0.2125)),
             ((-0.23, -0.19, 0.6375), (0.02, 0.02, 0.2125)), ((-0.23, 0, 0.77), (0.02, 0.21, 0.08))]
    for pos, half in parts:
        scene.add_mass_geom(body, scene.DENSITY, type=scene.BOX, pos=pos, size=half,
                            rgba=scene.WOOD)  # fmt: skip
    seat_and_back = (((-0.23, 0, 0.65), (0.02, 0.21, 0.2)), ((0, 0, 0.2375), (0.21, 0.21, 0.2375)))
    for pos, half in seat_and_back:
        scene.add_object_geom(body, type=scene.BOX, pos=pos, size=half, density=0.0)


_OBJECT_BUILDERS = {
    "chair": _chair,
    "trophy": props.trophy,
    "headphone": lambda body: props.headphone(body, y_offset=-0.05),
    "package_a": props.box((0.2, 0.1, 0.15)),
    "package_b": props.box((0.25, 0.2, 0.1)),
    "snow_globe": props.snow_globe,
}
