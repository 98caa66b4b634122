"""The Unitree H1 robot (with or without two Shadow E3M5 hands) for MJX: model specs and accessors.

Three variants, all with HumanoidBench's joint/actuator order and gains (spec §2, §5):

  "h1hand":   H1 + wrist yaw + two Shadow hands; nq 76, nv 75, nu 61, observation 151.
  "h1strong": h1hand with HumanoidBench's stronger hand actuators (highbar_hard): every hand
              actuator but WRJ2 has kp 50 and force range +-50 (h1hand: kp 0.4-8, +-1 to +-5).
  "h1":       H1 without hands or wrist yaw;       nq 26, nv 25, nu 19, observation 51.

Tasks build a scene on `robot_spec(...)` (robot + floor + options + keyframe), compile it, and wrap
the compiled `MjModel` in `Robot`, which holds the static indices used by rewards and observations.
Every accessor takes an `mjx.Data` (unbatched; vmap for a batch) and reads the fields `mjx.step`
returns, i.e. HumanoidBench's convention: kinematics and sensors of the last substep's forward pass.

Collision bits (the robot never collides with itself, HumanoidBench deviation, docs/robot.md):
robot colliders have contype=ROBOT_CONTYPE (2), conaffinity=ROBOT_CONAFFINITY (1); the floor has
contype=WORLD_CONTYPE (1), conaffinity=WORLD_CONAFFINITY (2). Scene geoms that the robot must touch
use the world bits; a free object that must also rest on the floor or on other objects uses
contype=conaffinity=3.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs.physics import Simulator

ASSET_DIR = Path(__file__).resolve().parents[2] / "assets" / "h1_shadow"
VARIANTS = {"h1hand": "h1_shadow.xml", "h1strong": "h1_shadow.xml", "h1": "h1.xml"}
HAND_VARIANTS = ("h1hand", "h1strong")
STRONG_HAND_KP, STRONG_HAND_FORCE = 50.0, 50.0
CONTACT_PROFILES = ("locomotion", "manipulation")

ROBOT_CONTYPE, ROBOT_CONAFFINITY = 2, 1
WORLD_CONTYPE, WORLD_CONAFFINITY = 1, 2

N_SUBSTEPS = 10  # HumanoidBench frame_skip: 10 x 0.002 s = one 50 Hz control step
CONTROL_DT = 0.02

_SIDES = ("left", "right")
_LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle")
_ARM = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")
# qpos order of one hand (kinematic tree order: wrist, palm, FF, MF, RF, LF, TH).
_HAND_JOINTS = (
    "WRJ2", "WRJ1", "FFJ4", "FFJ3", "FFJ2", "FFJ1", "MFJ4", "MFJ3", "MFJ2", "MFJ1",
    "RFJ4", "RFJ3", "RFJ2", "RFJ1", "LFJ5", "LFJ4", "LFJ3", "LFJ2", "LFJ1",
    "THJ5", "THJ4", "THJ3", "THJ2", "THJ1",
)  # fmt: skip
# actuator order of one hand (HumanoidBench: thumb first; J0 drives the J1+J2 fixed tendon).
_HAND_ACTUATORS = (
    "WRJ2", "WRJ1", "THJ5", "THJ4", "THJ3", "THJ2", "THJ1", "FFJ4", "FFJ3", "FFJ0",
    "MFJ4", "MFJ3", "MFJ0", "RFJ4", "RFJ3", "RFJ0", "LFJ5", "LFJ4", "LFJ3", "LFJ0",
)  # fmt: skip


def _leg_names() -> list[str]:
    return [f"{s}_{j}" for s in _SIDES for j in _LEG]


def _arm_names(side: str, wrist: bool) -> list[str]:
    return [f"{side}_{j}" for j in _ARM] + ([f"{side}_wrist_yaw"] if wrist else [])


def _hand(prefix: str, names: tuple[str, ...], act: bool) -> list[str]:
    return [f"{prefix}_A_{n}" if act else f"{prefix}_{n}" for n in names]


H1_JOINT_NAMES = tuple(
    _leg_names() + ["torso"] + _arm_names("left", False) + _arm_names("right", False)
)
JOINT_NAMES = tuple(
    _leg_names() + ["torso"]
    + _arm_names("left", True) + _hand("lh", _HAND_JOINTS, False)
    + _arm_names("right", True) + _hand("rh", _HAND_JOINTS, False)
)  # fmt: skip
"""Hinge joints of h1hand in qpos order (after the 7 free-joint entries): 69 names."""
H1_ACTUATOR_NAMES = H1_JOINT_NAMES
ACTUATOR_NAMES = tuple(
    _leg_names() + ["torso"] + _arm_names("left", True) + _arm_names("right", True)
    + _hand("lh", _HAND_ACTUATORS, True) + _hand("rh", _HAND_ACTUATORS, True)
)  # fmt: skip
"""h1hand actuators in action order: 61 names."""

_HAND_BODIES = (
    "wrist", "palm", "ffknuckle", "ffproximal", "ffmiddle", "ffdistal", "mfknuckle",
    "mfproximal", "mfmiddle", "mfdistal", "rfknuckle", "rfproximal", "rfmiddle", "rfdistal",
    "lfmetacarpal", "lfknuckle", "lfproximal", "lfmiddle", "lfdistal", "thbase", "thproximal",
    "thhub", "thmiddle", "thdistal",
)  # fmt: skip


def _hand_geoms() -> tuple[str, ...]:
    multi = {"wrist": 3, "palm": 5, "thmiddle": 2}
    names = []
    for p in ("lh", "rh"):
        for b in _HAND_BODIES:
            n = multi.get(b, 1)
            names += [f"{p}_{b}{k}" for k in range(n)] if n > 1 else [f"{p}_{b}"]
    return tuple(names)


GEOM_GROUPS: dict[str, tuple[str, ...]] = {
    "feet": ("left_foot", "right_foot"),
    "legs": ("left_thigh", "left_shin", "right_thigh", "right_shin"),
    "body": ("pelvis", "torso", "head"),
    "arms": ("left_upper_arm", "left_forearm", "right_upper_arm", "right_forearm"),
    "hands": _hand_geoms(),
    "links": (
        "left_hip_yaw", "left_hip_roll", "left_ankle", "right_hip_yaw", "right_hip_roll",
        "right_ankle", "shoulders", "left_shoulder_pitch", "left_shoulder_roll",
        "right_shoulder_pitch", "right_shoulder_roll",
    ),  # fmt: skip
}
"""Robot collider names by group (h1hand). The h1 variant has no "hands"; its arms end in
"left_fist"/"right_fist" spheres, listed under "arms" by `Robot.geom_groups`. "links" are
the capsules of the hip yaw/roll and shoulder pitch/roll links, the ankle housings and the
shoulder housings of the torso (docs/robot.md, collider fit): no contact profile turns them on
(each would add floor contacts to every task); obstacle tasks collide them with their
obstacles, and every contact rule that tests robot geoms (`overlap.PairQuery`) includes them."""
HAND_FLOOR_GEOMS: dict[str, tuple[str, ...]] = {
    "all": GEOM_GROUPS["hands"],
    "palms": tuple(n for n in GEOM_GROUPS["hands"] if "_wrist" in n or "_palm" in n),
    "none": (),
}
"""The hand colliders that touch the floor, by `hand_floor` value (sirl_jax/hb_compat.py):
HumanoidBench's every one, the wrist and palm boxes (16 of 62), or none."""
_H1_FISTS = ("left_fist", "right_fist")

# groups that collide with the world in each contact profile
_PROFILE_GROUPS = {
    "locomotion": ("feet", "legs", "body", "arms"),
    "manipulation": ("feet", "legs", "body", "arms", "hands"),
}


def _check(name: str, value: str, allowed) -> None:
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not supported; allowed: {sorted(allowed)}")


def robot_spec(variant: str = "h1hand", contacts: str = "locomotion") -> mujoco.MjSpec:
    """A fresh MjSpec of the robot on a floor, with options, sensors and the "stand" keyframe.

    Args:
      variant: "h1hand" (61 actuators), "h1strong" (h1hand with strong hands) or "h1" (19
        actuators, no hands).
      contacts: "locomotion" (feet, legs, body and arms touch the world; hands do not) or
        "manipulation" (the hand colliders touch the world too).
    Returns:
      An uncompiled `mujoco.MjSpec`; add scene bodies/geoms, then `.compile()`.
    """
    _check("variant", variant, VARIANTS)
    _check("contacts", contacts, CONTACT_PROFILES)
    spec = mujoco.MjSpec.from_file(str(ASSET_DIR / VARIANTS[variant]))
    if variant in HAND_VARIANTS:
        on = set(GEOM_GROUPS["hands"]) if contacts == "manipulation" else set()
        for geom in spec.geoms:
            if geom.name in GEOM_GROUPS["hands"]:
                geom.contype = ROBOT_CONTYPE if geom.name in on else 0
                geom.conaffinity = ROBOT_CONAFFINITY if geom.name in on else 0
    if variant == "h1strong":
        for actuator in spec.actuators:
            if actuator.name.startswith(("lh_A_", "rh_A_")) and not actuator.name.endswith("WRJ2"):
                actuator.gainprm[0], actuator.biasprm[1] = STRONG_HAND_KP, -STRONG_HAND_KP
                actuator.forcerange = (-STRONG_HAND_FORCE, STRONG_HAND_FORCE)
    return spec


def set_hand_floor(spec: mujoco.MjSpec, which: str) -> None:
    """The hand colliders of `HAND_FLOOR_GEOMS[which]` touch the floor (and the few scene geoms
    that carry the floor's contype: walls, the truck, the high bar) besides whatever a contact
    profile already gives them. A spec without hands (the h1 variant) is left as it is."""
    _check("hand_floor", which, HAND_FLOOR_GEOMS)
    for name in HAND_FLOOR_GEOMS[which]:
        geom = spec.geom(name)
        if geom is None:
            return  # the h1 variant: no hands
        geom.conaffinity = int(geom.conaffinity) | ROBOT_CONAFFINITY


def set_max_contact_points(spec: mujoco.MjSpec, k: int) -> None:
    """MJX contact budget: after the collision functions, keep only the k most penetrating
    contacts (all of one condim; every scene here is condim 3), so the constraint solver works on
    k contact slots instead of every slot the kept pairs can fill. Active contacts (dist < 0)
    rank first, so nothing that pushes is dropped while fewer than k touch; when k are active at
    once the env reports it (`physics.OVERFLOW_METRIC`). MJX-JAX only (Warp sizes its own pool).
    `HumanoidEnv` applies a task's `max_contact_points` with it, after the scene and the hand
    floor."""
    if k < 1:
        raise ValueError(f"max_contact_points must be >= 1, got {k}")
    spec.add_numeric(name="max_contact_points", data=[float(k)])


def load_model(variant: str = "h1hand", contacts: str = "locomotion") -> mujoco.MjModel:
    """The compiled robot-on-floor model (no scene)."""
    return robot_spec(variant, contacts).compile()


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"the model has no {kind.name[5:].lower()} named {name!r}")
    return i


class Robot:
    """Static ids and indices of the robot inside a compiled model (robot + any scene).

    The robot's free joint must be the model's first joint, so the robot owns qpos[:nq_robot]
    and qvel[:nv_robot] (scene objects come after it, as in HumanoidBench).
    """

    def __init__(self, model: mujoco.MjModel):
        self.variant = (
            "h1hand"
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "lh_WRJ2") >= 0
            else "h1"
        )
        joints = JOINT_NAMES if self.variant == "h1hand" else H1_JOINT_NAMES
        actuators = ACTUATOR_NAMES if self.variant == "h1hand" else H1_ACTUATOR_NAMES
        if model.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE or model.joint(0).name != "free_base":
            raise ValueError("the robot's free joint 'free_base' must be the model's first joint")
        adr = [model.jnt_qposadr[_id(model, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in joints]
        if adr != list(range(7, 7 + len(joints))):
            raise ValueError(f"robot joints are not in HumanoidBench qpos order: {adr}")
        ids = [_id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in actuators]
        if ids != list(range(len(actuators))):
            raise ValueError("robot actuators must come first, in HumanoidBench order")
        self.joint_names, self.actuator_names = joints, actuators
        self.nq_robot, self.nv_robot, self.nu = 7 + len(joints), 6 + len(joints), len(actuators)
        self.qpos_slice, self.qvel_slice = slice(0, self.nq_robot), slice(0, self.nv_robot)
        self.obs_size = self.nq_robot + self.nv_robot
        low, high = model.actuator_ctrlrange[: self.nu].T
        self.ctrl_low = jnp.asarray(low, jnp.float32)
        self.ctrl_high = jnp.asarray(high, jnp.float32)
        self.keyframe_qpos = np.array(model.key_qpos[_id(model, mujoco.mjtObj.mjOBJ_KEY, "stand")])
        self.keyframe_action = self._holding_action(model, low, high)
        self._torso = _id(model, mujoco.mjtObj.mjOBJ_BODY, "torso_link")
        self._pelvis = _id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        self._head = _id(model, mujoco.mjtObj.mjOBJ_SITE, "head")
        sensor = _id(model, mujoco.mjtObj.mjOBJ_SENSOR, "pelvis_subtreelinvel")
        self._com_vel_adr = int(model.sensor_adr[sensor])
        self.site_ids = {model.site(i).name: i for i in range(model.nsite)}
        groups = {k: v for k, v in GEOM_GROUPS.items() if self.variant == "h1hand" or k != "hands"}
        if self.variant == "h1":
            groups["arms"] = groups["arms"] + _H1_FISTS
        self.geom_groups = groups
        self.geom_ids = {
            k: np.array([_id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in v], np.int32)
            for k, v in groups.items()
        }

    def _holding_action(self, model: mujoco.MjModel, low, high) -> np.ndarray:
        """[A] normalised action whose position targets equal the keyframe pose."""
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, _id(model, mujoco.mjtObj.mjOBJ_KEY, "stand"))
        mujoco.mj_forward(model, data)
        target = np.asarray(data.actuator_length[: self.nu], np.float64)  # gear 1
        return np.clip(2.0 * (target - low) / (high - low) - 1.0, -1.0, 1.0).astype(np.float32)

    def action_to_ctrl(self, action: jax.Array) -> jax.Array:
        """[..., A] action in [-1, 1] -> [..., A] ctrl = low + (a+1)/2 (high-low) (not clipped;
        MuJoCo/MJX clamp ctrl to ctrlrange)."""
        return self.ctrl_low + (action + 1.0) * 0.5 * (self.ctrl_high - self.ctrl_low)

    def head_height(self, d: mjx.Data) -> jax.Array:
        """[] z of the `head` site (torso_link + (0, 0, 0.7))."""
        return d.site_xpos[self._head, 2]

    def torso_upright(self, d: mjx.Data) -> jax.Array:
        """[] zz entry of torso_link's rotation matrix."""
        return d.xmat[self._torso, 2, 2]

    def pelvis_upright(self, d: mjx.Data) -> jax.Array:
        """[] zz entry of the pelvis rotation matrix (HumanoidBench reach's `xmat[1][8]`)."""
        return d.xmat[self._pelvis, 2, 2]

    def pelvis_height(self, d: mjx.Data) -> jax.Array:
        """[] qpos[2], the root z used by the fall terminations."""
        return d.qpos[2]

    def com_velocity(self, d: mjx.Data) -> jax.Array:
        """[3] world-frame linear velocity of the robot's centre of mass (pelvis subtree)."""
        return jax.lax.dynamic_slice_in_dim(d.sensordata, self._com_vel_adr, 3)

    def actuator_forces(self, d: mjx.Data) -> jax.Array:
        """[A] actuator forces of the robot."""
        return d.actuator_force[: self.nu]

    def site_pos(self, d: mjx.Data, name: str) -> jax.Array:
        """[3] world position of a site (head, imu, left_foot, right_foot, left_hand, ...)."""
        if name not in self.site_ids:
            raise ValueError(f"unknown site {name!r}; sites: {sorted(self.site_ids)}")
        return d.site_xpos[self.site_ids[name]]

    def observation(self, d: mjx.Data) -> jax.Array:
        """[nq_robot + nv_robot] the robot's qpos then qvel (151 for h1hand, 51 for h1)."""
        return jnp.concatenate([d.qpos[self.qpos_slice], d.qvel[self.qvel_slice]])


def keyframe_data(
    model: mujoco.MjModel, mx: mjx.Model, key: str = "stand", sim: Simulator | None = None
) -> mjx.Data:
    """An `mjx.Data` at a keyframe (qpos, qvel, ctrl from the key), after a forward pass.

    `sim`: the `physics.Simulator` of `mx` when it is not MJX-JAX; the data then comes back
    without Warp's contact pool (`Simulator.detach_pool`), ready to broadcast over envs.
    """
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, _id(model, mujoco.mjtObj.mjOBJ_KEY, key))
    d = mjx.make_data(mx) if sim is None else sim.make_data(mx)
    d = d.replace(
        qpos=jnp.asarray(data.qpos, d.qpos.dtype),
        qvel=jnp.asarray(data.qvel, d.qvel.dtype),
        ctrl=jnp.asarray(data.ctrl, d.ctrl.dtype),
    )
    # jit-compiled forward: every leaf comes back as a device array, so a jitted step sees the
    # same argument types on its first and later calls (no second compile).
    if sim is None:
        return jax.jit(mjx.forward)(mx, d)
    return sim.detach_pool(jax.jit(mjx.forward)(mx, sim.attach_pool(d)))
