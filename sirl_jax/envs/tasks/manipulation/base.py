"""What every manipulation task shares: the `ManipulationTask` base and its helpers.

A manipulation task holds only what is particular to it: its scene (`build_scene`, from
`sirl_jax.envs.tasks.scene`'s fixtures, objects and props), its keyframe (`robot_qpos`,
`object_qpos`), its state, reward and observation extras. `ManipulationTask.build` does the rest
the same way for all of them: the hands' contact profile, keyframe 0 and MJX's broad-phase cap.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from sirl_jax.envs.humanoid import Task
from sirl_jax.envs.task_parts import MANIPULATION_BUDGET
from sirl_jax.envs.tasks import scene
from sirl_jax.hb_compat import HB

# HumanoidBench's task keyframes put the robot in the stand pose; some set arm joints as well.
STAND_ROBOT_QPOS = (0, 0, 0.98, 1, 0, 0, 0) + (0, 0, -0.4, 0.8, -0.4) * 2 + (0,) * 59



def set_keyframe(
    spec: mujoco.MjSpec, robot_qpos: Sequence[float], object_qpos: Sequence[float]
) -> None:
    """Keyframe 0 = HumanoidBench's task `qpos0`: the robot's 76 entries then the objects'."""
    if len(robot_qpos) != len(STAND_ROBOT_QPOS):
        n = len(STAND_ROBOT_QPOS)
        raise ValueError(f"robot keyframe needs {n} values, got {len(robot_qpos)}")
    spec.keys[0].qpos = [float(v) for v in (*robot_qpos, *object_qpos)]


def with_robot_entries(values: dict[int, float]) -> tuple[float, ...]:
    """The stand keyframe with some robot qpos entries replaced ({qpos index: value})."""
    qpos = list(STAND_ROBOT_QPOS)
    for i, v in values.items():
        qpos[i] = v
    return tuple(qpos)


def free_joint_adr(model: mujoco.MjModel, joint: str) -> tuple[int, int]:
    """(qpos address, dof address) of a free joint."""
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if j < 0:
        raise ValueError(f"the model has no joint named {joint!r}")
    return int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])


def body_id(model: mujoco.MjModel, name: str) -> int:
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if i < 0:
        raise ValueError(f"the model has no body named {name!r}")
    return i


def hand_sites(robot, data) -> jax.Array:
    """[2, 3] the left_hand and right_hand sites."""
    return jnp.stack([robot.site_pos(data, "left_hand"), robot.site_pos(data, "right_hand")])


def euler_to_quat(angles: jax.Array) -> jax.Array:
    """[3] (roll, pitch, yaw) -> [4] (w, x, y, z), HumanoidBench's `euler_to_quat` convention."""
    c, s = jnp.cos(angles / 2), jnp.sin(angles / 2)
    cr, cp, cy = c[0], c[1], c[2]
    sr, sp, sy = s[0], s[1], s[2]
    return jnp.stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ])  # fmt: skip


def geom_ids(model: mujoco.MjModel, names: Sequence[str]) -> np.ndarray:
    ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in names])
    if (ids < 0).any():
        raise ValueError(f"unknown geoms: {[n for n, i in zip(names, ids, strict=True) if i < 0]}")
    return ids



class ManipulationTask(Task):
    """A HumanoidBench manipulation task (h1hand, or h1strong for highbar).

    `build`: the hand colliders touch free objects only (`scene.use_hand_contacts`), then the
    task's `build_scene`, then HumanoidBench's contact set unless `contact_set` is "reduced"
    (`scene.use_hb_contacts`), then keyframe 0 = `robot_qpos` followed by `object_qpos`
    (HumanoidBench's task `qpos0`), then `max_geom_pairs` (MJX keeps that many candidate pairs
    per collision function; the scene's fixtures are many static geoms). The env applies
    `max_contact_points`, MJX's contact budget (the solver sees that many contacts, the most
    penetrating; `MANIPULATION_BUDGET` unless the task sets its own; docs/tasks.md, "Contact
    budget").
    """

    contacts = "manipulation"
    robot_qpos: Sequence[float] = STAND_ROBOT_QPOS
    """The robot's 76 keyframe entries (HumanoidBench's task keyframe)."""
    object_qpos: Sequence[float] = ()
    """The keyframe entries of the task's joints after the robot's (free objects, hinges)."""
    max_geom_pairs: int = 8
    max_contact_points = MANIPULATION_BUDGET
    prism_sides: int = scene.PRISM_SIDES
    """Sides of the prism that stands in for each colliding cylinder in the `hb` contact set
    (`scene.use_hb_contacts`)."""

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        scene.use_hand_contacts(spec)
        self.build_scene(spec, variant)
        if self.contact_set == HB:
            scene.use_hb_contacts(spec, self.prism_sides)
        set_keyframe(spec, self.robot_qpos, self.object_qpos)
        scene.set_max_geom_pairs(spec, self.max_geom_pairs)

    @abc.abstractmethod
    def build_scene(self, spec: mujoco.MjSpec, variant: str) -> None:
        """Adds the task's fixtures, objects and sites to `spec` (keyframe and cap excluded)."""
