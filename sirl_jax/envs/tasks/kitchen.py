"""Four kitchen chores in a fixed order: open the microwave, move the kettle, turn the bottom
burner's knob, flip the light switch (HumanoidBench Kitchen, after the adept Franka kitchen).

The scene is built here from primitives with `MjSpec` (HumanoidBench's kitchen XML does not
compile under MuJoCo 4.0). Frames and numbers are HumanoidBench's: the furniture hangs off a
desk frame at (-0.1, 0.75, 0); each part below is given in its own frame, as HumanoidBench nests
them. Object qpos (21, after the robot's 76), in HumanoidBench's order:

    0-7   knob_Joint_k, burner_Joint_k for k = 1..4 (knob 2 / burner 2 = "bottom burner" [2, 3],
          knob 4 / burner 4 = "top burner" [6, 7])
    8-9   lightswitch_joint, light_joint
    10    slidedoor_joint
    11-12 leftdoorhinge, rightdoorhinge
    13    microjoint
    14-20 free_kettle (world position, quaternion)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs.humanoid import Task, set_max_geom_pairs
from sirl_jax.envs.tasks import manip

N_ROBOT_QPOS = len(manip.STAND_ROBOT_QPOS)  # 76
N_OBJECT_QPOS = 21
SUBTASKS = ("microwave", "kettle", "bottom burner", "light switch")
N_SUBTASKS = len(SUBTASKS)
# HumanoidBench's OBS_ELEMENT_INDICES (object qpos) and OBS_ELEMENT_GOALS of the four subtasks.
SUBTASK_INDICES = {
    "microwave": (13,), "kettle": (14, 15, 16, 17, 18, 19, 20), "bottom burner": (2, 3),
    "light switch": (8, 9),
}  # fmt: skip
SUBTASK_GOALS = {
    "microwave": (-0.75,), "kettle": (-0.23, 0.75, 1.0, 0.99, 0.0, 0.0, -0.06),
    "bottom burner": (-0.88, -0.01), "light switch": (-0.69, -0.05),
}  # fmt: skip
# HumanoidBench's goals of the elements no subtask uses (not rewarded).
OTHER_GOALS = {"top burner": (-0.92, -0.01), "slide cabinet": (0.37,), "hinge cabinet": (0.0, 1.45)}
BONUS_THRESH = 0.3
MAX_GEOM_PAIRS = 12

# Keyframe (HumanoidBench's "qpos0"): root (0, -0.6, 0.98) with the quaternion it writes as
# (1, 0, 0, 1.57), normalised here (yaw 2 atan(1.57) = 2.007 rad), legs in the stand pose.
ROOT_POS = (0.0, -0.6, 0.98)
_NORM = math.hypot(1.0, 1.57)
ROOT_QUAT = (1.0 / _NORM, 0.0, 0.0, 1.57 / _NORM)
KNOB_Q0, BURNER_Q0 = 1.25561e-05, 1.57437e-07
LIGHTSWITCH_Q0, LIGHT_Q0 = 8.24417e-05, 9.48283e-05
KETTLE_POS = (-0.269, 0.35, 0.994)
OBJECT_QPOS0 = (
    (KNOB_Q0, BURNER_Q0) * 4 + (LIGHTSWITCH_Q0, LIGHT_Q0) + (0.0,) * 4 + KETTLE_POS
    + (1.0, 0.0, 0.0, 0.0)
)  # fmt: skip

# -- the scene, HumanoidBench's numbers -------------------------------------------------------
DESK_POS = (-0.1, 0.75, 0.0)
Box = tuple[tuple[float, float, float], tuple[float, float, float]]  # (pos, half size)
# Counters (desk frame): the two cabinet bases, the left worktop and the four sink rims.
_COUNTERS: tuple[Box, ...] = (
    ((-0.86, -0.5, 0.46), (0.46, 1.07, 0.46)), ((0.907, -0.045, 0.46), (0.304, 0.606, 0.46)),
    ((-0.855, -0.508, 0.95), (0.463, 1.08, 0.03)),
    ((1.158, -0.04, 0.95), (0.05, 0.61, 0.076)), ((0.652, -0.04, 0.95), (0.05, 0.61, 0.076)),
    ((0.904, 0.401, 0.95), (0.204, 0.166, 0.076)), ((0.904, -0.611, 0.95), (0.206, 0.034, 0.076)),
)  # fmt: skip
# Oven (frame OVEN_POS in the desk): the stove block whose top (z 0.9934) carries the kettle.
OVEN_POS = (0.115, -0.2921, 0.9834)
_OVEN_BLOCK: Box = ((-0.017, 0.28, -0.5), (0.5, 0.602, 0.51))
# Knob k: body at (x, 0.22, z) turned by euler (1.57, 0, 0) (its z axis toward the robot), a
# hinge about z in [-1.57, 0]; burner k: body at (x, y, -0.02) on a slide along -z in
# [-0.009, 0], tied to its knob by knob = 174 burner. Stiffness 1 on burners 2-4 only.
_KNOBS = ((-0.148, 0.613), (-0.271, 0.613), (-0.148, 0.727), (-0.271, 0.727))
_BURNERS = ((0.206, -0.119), (-0.24, -0.119), (0.204, 0.322), (-0.237, 0.322))
_BURNER_STIFFNESS = (0.0, 1.0, 1.0, 1.0)
KNOB_RANGE, BURNER_RANGE, KNOB_PER_BURNER = (-1.57, 0.0), (-0.009, 0.0), 174.0
_KNOB_BAR: Box = ((0.0, 0.0, 0.038), (0.014, 0.048, 0.018))
_KNOB_DISC = (0.05, 0.008, 0.013)  # cylinder radius, half height, z: a box of the same area
KNOB_PART_MASS = 0.01  # bar and disc each
BURNER_MASS, BURNER_INERTIA = 0.01, 0.001
OVEN_DAMPING, OVEN_ARMATURE = 2.0, 0.001  # HumanoidBench's "oven" joint class
# Hood (frame HOOD_POS in the desk) and the light switch (hinge about z in [-0.7, 0] at
# LIGHTSWITCH_POS in the hood, frictionloss 1), which drives the light block (slide along -z in
# [-0.05, 0], frictionloss 1) by switch = 14 light.
HOOD_POS = (0.1, 0.188, 1.70)
_HOOD_BLOCK: Box = ((0.0, 0.073, -0.046), (0.502, 0.336, 0.12))
LIGHTSWITCH_POS, LIGHT_POS = (-0.4, -0.2473, -0.05), (-0.0044, -0.3, -0.1361)
LIGHTSWITCH_RANGE, LIGHT_RANGE, SWITCH_PER_LIGHT = (-0.7, 0.0), (-0.05, 0.0), 14.0
_SWITCH_CAPSULE = ((0.0263, -0.065, 0.0), (-1.57, -0.4, 0.0), 0.021, 0.03)  # pos, euler, r, half
_LIGHT_PLATE: Box = ((-0.008, 0.4, -0.01), (0.4, 0.3, 0.015))
LIGHTSWITCH_MASS, LIGHT_MASS = 0.1, 0.01
_SWITCH_IPOS = (-0.0046, 0.35, 0.0131)  # HumanoidBench's <inertial> of both bodies
LIGHT_FRICTIONLOSS = 1.0
# Back walls (desk frame + (0, 0, -0.605)): frame pos, yaw, boxes.
_WALLS = (
    ((0.059, 0.584, 1.587), 0.0, (((-0.11, 0.06, 0.6), (1.26, 0.07, 0.6)),
                                  ((-0.11, 0.06, 0.145), (1.26, 0.08, 0.145)))),
    ((-1.305, -0.546, 1.587), 1.57, (((0.044, 0.06, 0.6), (1.079, 0.07, 0.6)),
                                     ((0.044, 0.06, 0.145), (1.079, 0.08, 0.145)))),
)  # fmt: skip
WALL_Z = -0.605
WALL_SEGMENT = 0.7  # m: walls cut into pieces MJX's broad phase can rank
# Cabinet joints share HumanoidBench's class defaults: damping 2, frictionloss 2, armature 0.01.
CABINET_DAMPING, CABINET_FRICTIONLOSS, CABINET_ARMATURE = 2.0, 2.0, 0.01
_CABINET_JOINT = {
    "limited": mujoco.mjtLimited.mjLIMITED_TRUE, "damping": CABINET_DAMPING,
    "frictionloss": CABINET_FRICTIONLOSS, "armature": CABINET_ARMATURE,
}  # fmt: skip


# Slide cabinet (frame in the desk): shell; door on a slide along x in [0, 0.44].
SLIDE_CABINET_POS = (0.4, 0.3, 1.98)
_SLIDE_SHELL: tuple[Box, ...] = (
    ((-0.225, 0, -0.18), (0.223, 0.3, 0.02)), ((0.224, 0, 0), (0.226, 0.3, 0.2)),
    ((-0.225, 0, 0.18), (0.223, 0.3, 0.02)), ((-0.426, 0, 0), (0.022, 0.3, 0.16)),
    ((-0.2, 0.276, 0), (0.2, 0.024, 0.16)),
)  # fmt: skip
SLIDE_DOOR_POS, SLIDE_RANGE = (-0.225, -0.32, 0.0), (0.0, 0.44)
_SLIDE_PANEL = (((0.0, -0.02, 0.0), (0.225, 0.03, 0.195)), 0.2)
# Handle bars (cylinders): (pos, axis, radius, half length, mass); axis "z" or "y".
Bar = tuple[tuple[float, float, float], str, float, float, float]
_SLIDE_HANDLE: tuple[Bar, ...] = (
    ((-0.183, -0.123, 0.0), "z", 0.022, 0.159, 0.1),
    ((-0.183, -0.06, -0.114), "y", 0.019, 0.053, 0.02),
    ((-0.183, -0.06, 0.114), "y", 0.019, 0.053, 0.02),
)  # fmt: skip
# Hinge cabinet (frame in the desk): shell; two doors on hinges about z.
HINGE_CABINET_POS = (-0.504, 0.28, 1.98)
_HINGE_SHELL: tuple[Box, ...] = (
    ((0, 0, 0), (0.04, 0.3, 0.2)), ((0.38, 0, 0), (0.02, 0.3, 0.2)),
    ((-0.38, 0, 0), (0.02, 0.3, 0.2)), ((-0.2, 0, 0.18), (0.16, 0.3, 0.02)),
    ((-0.2, 0, -0.18), (0.16, 0.3, 0.02)), ((0.2, 0, -0.18), (0.16, 0.3, 0.02)),
    ((0.2, 0, 0.18), (0.16, 0.3, 0.02)), ((-0.2, 0.28, 0), (0.16, 0.02, 0.16)),
    ((0.2, 0.28, 0), (0.16, 0.02, 0.16)),
)  # fmt: skip
# (body, joint, body pos, range, panel x, handle x): the doors mirror each other.
_HINGE_DOORS = (
    ("hingeleftdoor", "leftdoorhinge", (-0.38, -0.32, 0.0), (-1.57, 0.0), 0.184, 0.302),
    ("hingerightdoor", "rightdoorhinge", (0.38, -0.32, 0.0), (0.0, 1.57), -0.185, -0.302),
)  # fmt: skip


def _hinge_door(panel_x: float, x: float) -> tuple[tuple[Box, float], tuple[Bar, ...]]:
    """A hinge door's panel (0.2 kg) and handle bars at handle x `x`."""
    panel = (((panel_x, -0.015, 0.0), (0.193, 0.03, 0.2)), 0.2)
    bars = (((x, -0.128, 0.0), "z", 0.022, 0.16, 0.1),
            ((x, -0.061, 0.114), "y", 0.019, 0.053, 0.02),
            ((x, -0.061, -0.114), "y", 0.019, 0.053, 0.02))  # fmt: skip
    return panel, bars


# Microwave (frame in the desk, turned by yaw 0.25): shell; door on a hinge about z in
# [-2.094, 0] (opening toward the robot), a handle bar and two posts (capsules).
MICROWAVE_POS, MICROWAVE_YAW = (-0.75, -0.025, 0.99), 0.25
_MICROWAVE_SHELL: tuple[Box, ...] = (
    ((-0.316, 0.023, 0.187), (0.029, 0.199, 0.187)), ((0.236, 0.023, 0.187), (0.109, 0.199, 0.187)),
    ((-0.081, 0.191, 0.187), (0.207, 0.03, 0.187)), ((-0.08, -0.007, 0.355), (0.207, 0.169, 0.019)),
    ((-0.08, -0.008, 0.024), (0.207, 0.168, 0.024)), ((0.26, -0.197, 0.187), (0.085, 0.024, 0.187)),
)  # fmt: skip
MICRO_DOOR_POS, MICRO_RANGE = (-0.345, -0.176, 0.192), (-2.094, 0.0)
_MICRO_PANEL = (((0.259, -0.026, 0.0), (0.259, 0.024, 0.185)), 0.2)
_MICRO_HANDLE = (  # capsules (pos, axis, radius, half length, mass)
    ((0.475, -0.108, 0.0), "z", 0.02, 0.13, 0.02),
    ((0.475, -0.075, 0.13), "y", 0.02, 0.03, 0.02),
    ((0.475, -0.075, -0.13), "y", 0.02, 0.03, 0.02),
)  # fmt: skip
# Kettle (free; body frame at its base): body box, handle capsule along x on two posts, spout.
_KETTLE_BODY = (((0.0, 0.0, 0.058), (0.122, 0.122, 0.058)), 0.8)
_KETTLE_CAPSULES = (  # (pos, euler, radius, half length, mass)
    ((0.0, 0.0, 0.259), (0.0, 1.57, 0.0), 0.032, 0.1, 0.02),
    ((0.092, 0.0, 0.18), (0.0, 0.0, 0.0), 0.023, 0.06, 0.02),
    ((-0.092, 0.0, 0.18), (0.0, 0.0, 0.0), 0.023, 0.06, 0.02),
    ((-0.126, 0.0, 0.07), (0.0, 2.25, 0.0), 0.031, 0.05 - 0.031, 0.02),  # the r 0.031 cylinder
)  # fmt: skip
KETTLE_MASS = 0.88

_WOOD, _METAL, _BLACK = (0.46, 0.5, 0.6, 1), (0.75, 0.75, 0.78, 1), (0.15, 0.15, 0.15, 1)
_MARBLE, _WALL = (0.85, 0.85, 0.82, 1), (0.66, 0.7, 0.8, 1)


def _quat(euler: Sequence[float]) -> tuple[float, float, float, float]:
    """MuJoCo's default euler convention (intrinsic x, y, z; radians) as a quaternion."""
    q = np.zeros(4)
    mujoco.mju_euler2Quat(q, np.asarray(euler, float), "xyz")
    return tuple(float(v) for v in q)


_AXIS_QUAT = {"z": (1.0, 0.0, 0.0, 0.0), "y": _quat((1.57, 0.0, 0.0))}  # euler "1.57 0 0"


# -- reward -----------------------------------------------------------------------------------
def subtask_distances(obj_qpos: jax.Array) -> jax.Array:
    """[21] object qpos -> [4] distances of the subtasks (microwave, kettle, bottom burner,
    light switch) to their goals: the norm over each subtask's object-qpos entries."""
    return jnp.stack([
        jnp.linalg.norm(obj_qpos[jnp.array(SUBTASK_INDICES[n])] - jnp.array(SUBTASK_GOALS[n]))
        for n in SUBTASKS
    ])  # fmt: skip


def kitchen_init_state(obj_qpos: jax.Array) -> dict[str, jax.Array]:
    """The task state of an episode starting at `obj_qpos` [21]: the next subtask (0) and
    whether it is "armed" (seen outside its threshold since it became the next one)."""
    return {
        "next": jnp.zeros((), jnp.int32),
        "armed": subtask_distances(obj_qpos)[0] >= BONUS_THRESH,
    }


def kitchen_reward(
    obj_qpos: jax.Array, state: dict[str, jax.Array], strict_order: bool = True
) -> tuple[jax.Array, dict[str, jax.Array], dict[str, jax.Array]]:
    """HumanoidBench Kitchen: +1 for each subtask completed in this step, in the order
    microwave, kettle, bottom burner, light switch; a subtask is within threshold when the
    norm of (its object-qpos entries - goal) is below 0.3, and each is paid once.

    strict_order=False (HumanoidBench): the remaining subtasks are scanned in order and every
    one within threshold counts as long as all remaining ones before it are within threshold
    now, so a later subtask done early is paid in the step the earlier ones get done.
    strict_order=True: only the next subtask can be completed, at most one per step, and only
    by entering its threshold after it became the next one (it must be seen outside it since:
    "armed"); a subtask done out of order must be undone and redone.

    Args:
      obj_qpos: [21] object qpos (`SUBTASK_INDICES`). state: {"next": [] int32 0..4, "armed":
      [] bool}.

    Returns:
      (reward [], new state, terms: success_subtasks, success, and the four distances).
    """
    dist = subtask_distances(obj_qpos)
    inside = dist < BONUS_THRESH
    nxt, armed = state["next"], state["armed"]
    order = jnp.arange(N_SUBTASKS)
    if strict_order:
        current = inside[jnp.minimum(nxt, N_SUBTASKS - 1)] & (nxt < N_SUBTASKS)
        paid = current & armed
        count = paid.astype(jnp.int32)
        new_next = nxt + count
        armed_next = ~inside[jnp.minimum(new_next, N_SUBTASKS - 1)]
        new_armed = jnp.where(paid, armed_next, armed | ~current)
    else:
        remaining = order >= nxt
        run = jnp.cumprod((inside | ~remaining).astype(jnp.int32)) * remaining
        count = jnp.sum(run).astype(jnp.int32)
        new_next = nxt + count
        new_armed = ~inside[jnp.minimum(new_next, N_SUBTASKS - 1)]
    new_state = {"next": new_next, "armed": new_armed}
    terms = {
        "success_subtasks": new_next.astype(jnp.float32),
        "success": (new_next >= N_SUBTASKS).astype(jnp.float32),
        **{f"{name.replace(' ', '_')}_distance": dist[i] for i, name in enumerate(SUBTASKS)},
    }
    return count.astype(jnp.float32), new_state, terms


# -- the task ---------------------------------------------------------------------------------
class KitchenTask(Task):
    """The adept kitchen: counters, stove with four knob-driven burners, hood with a light
    switch, slide and hinge wall cabinets, microwave, and a free 0.88 kg kettle on the bottom
    left burner; the robot stands 0.7 m in front of the stove. +1 per subtask done in the order
    microwave (hinge to -0.75), kettle (to the top left burner), bottom burner (knob to -0.88),
    light switch (to -0.69); terminates when all four are done (return 4 = the success bar).
    No reset noise (HumanoidBench's is 0 here). Observation: qpos only, robot (76) then
    objects (21): 97. Task state: {"next": subtask index 0..4, "armed": bool}.

    HumanoidBench bug (fixed by strict_order=True, the default; False reproduces it): its
    ENFORCE_TASK_ORDER enforces only the order of payment, not of the work - `get_reward` pays an
    element when `complete and (all_completed_so_far ...)`, where all_completed_so_far asks
    whether the earlier *remaining* elements are within threshold now, so a kettle put on its
    goal before the microwave is opened is paid together with the microwave (+2 in that step)
    and any order of the chores earns the full return of 4.

    Scene deviations (all else is HumanoidBench's geometry, joints and masses): colliders only
    (HumanoidBench's visual meshes are left out); MJX has no cylinder-box pair, so the knob's
    disc (an r 0.05 cylinder, 0.01 kg) is a box of the same area and mass, the cabinet handle
    cylinders are capsules of the same length (mass and inertia from non-colliding cylinders)
    and the kettle's spout cylinder is a capsule of the same length carrying its 0.02 kg;
    the counters' decorative faucet and handles, the oven's handles and the thin sink rims
    inside the taller ones are left out; contact margins, solref/solimp and the kettle's
    condim 4 are MuJoCo's defaults (condim 3). Masses: every HumanoidBench mass here comes from
    `mass` attributes or `<inertial>`s (its visual mesh geoms are outside the inertia group),
    so none is estimated: kettle 0.88 kg, microwave door 0.26 kg, knobs 0.02 kg, ...

    Contacts (the manipulation profile): the moving parts (knobs, switch, doors, handles)
    touch the hands and the kettle; the static furniture touches the kettle only; the kettle
    touches the hands, the floor and all furniture. The robot's body passes through the
    furniture and the hands through the static parts. The root quaternion of HumanoidBench's
    keyframe, written (1, 0, 0, 1.57), is kept normalised (yaw 2.007 rad, the robot turned
    26 deg toward the microwave), so the reset observation shows the unit quaternion."""

    name = "kitchen"
    metric_names = (
        "success_subtasks", "success", "microwave_distance", "kettle_distance",
        "bottom_burner_distance", "light_switch_distance",
    )  # fmt: skip
    contacts = "manipulation"
    reset_noise = 0.0
    full_state_obs = False
    extra_obs_size = N_OBJECT_QPOS
    qvel_obs = False

    def __init__(self, strict_order: bool = True):
        self.strict_order = bool(strict_order)

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        manip.use_hand_contacts(spec)
        desk = spec.worldbody.add_body(name="desk", pos=DESK_POS)
        counters = desk.add_body(name="counters")
        for k, (pos, half) in enumerate(_COUNTERS):
            manip.add_fixture(spec, counters, name=f"counter_{k}", pos=pos, size=half,
                              rgba=_MARBLE if pos[2] > 0.9 else _WOOD)  # fmt: skip
        self._build_oven(spec, desk)
        walls = desk.add_body(name="backwall", pos=(0.0, 0.0, WALL_Z))
        for k, (pos, yaw, boxes) in enumerate(_WALLS):
            wall = walls.add_body(name=f"wall_{k}", pos=pos, quat=_quat((0.0, 0.0, yaw)))
            for j, (bpos, half) in enumerate(boxes):
                manip.add_segmented_box(wall, f"wall_{k}{j}", bpos, half, WALL_SEGMENT,
                                        contype=manip.FIXTURE, conaffinity=0, rgba=_WALL)
        self._build_slide_cabinet(spec, desk)
        self._build_hinge_cabinet(spec, desk)
        self._build_microwave(spec, desk)
        kettle = spec.worldbody.add_body(name="kettle", pos=(*KETTLE_POS[:2], 1.0))
        kettle.add_freejoint(name="free_kettle")
        (pos, half), mass = _KETTLE_BODY
        manip.add_object_geom(kettle, name="kettle_body", type=manip.BOX, pos=pos, size=half,
                              mass=mass, rgba=(0.9, 0.9, 0.9, 1))  # fmt: skip
        for k, (pos, euler, radius, half, mass) in enumerate(_KETTLE_CAPSULES):
            manip.add_object_geom(kettle, name=f"kettle_capsule_{k}", type=manip.CAPSULE,
                                  pos=pos, quat=_quat(euler), size=(radius, half, 0), mass=mass,
                                  rgba=(0.6, 0.45, 0.3, 1))  # fmt: skip
        manip.set_keyframe(
            spec, manip.with_robot_entries({1: ROOT_POS[1], 2: ROOT_POS[2], 3: ROOT_QUAT[0],
                                            6: ROOT_QUAT[3]}), OBJECT_QPOS0,
        )  # fmt: skip
        set_max_geom_pairs(spec, MAX_GEOM_PAIRS)

    def _build_oven(self, spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
        oven = desk.add_body(name="ovenroot", pos=OVEN_POS)
        pos, half = _OVEN_BLOCK
        manip.add_fixture(spec, oven, name="oven_block", pos=pos, size=half, rgba=_BLACK)
        knob_quat = _quat((1.57, 0.0, 0.0))
        disc_half = _KNOB_DISC[0] * math.sqrt(math.pi) / 2  # a square of the disc's area
        for k in range(4):
            x, z = _KNOBS[k]
            knob = oven.add_body(name=f"knob {k + 1}", pos=(x, 0.22, z), quat=knob_quat)
            knob.add_joint(name=f"knob_Joint_{k + 1}", axis=(0, 0, 1), range=KNOB_RANGE,
                           limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=OVEN_DAMPING,
                           armature=OVEN_ARMATURE)  # fmt: skip
            bar_pos, bar_half = _KNOB_BAR
            _moving_geom(knob, manip.BOX, pos=bar_pos, size=bar_half, mass=KNOB_PART_MASS,
                         rgba=(0.8, 0.1, 0.1, 1))  # fmt: skip
            _moving_geom(knob, manip.BOX, pos=(0, 0, _KNOB_DISC[2]),
                         size=(disc_half, disc_half, _KNOB_DISC[1]), mass=KNOB_PART_MASS,
                         rgba=_METAL)  # fmt: skip
            bx, by = _BURNERS[k]
            burner = oven.add_body(name=f"Burner {k + 1}", pos=(bx, by, -0.02))
            manip.set_inertial(burner, BURNER_MASS, (BURNER_INERTIA,) * 3)
            burner.add_joint(name=f"burner_Joint_{k + 1}", type=mujoco.mjtJoint.mjJNT_SLIDE,
                             axis=(0, 0, -1), range=BURNER_RANGE,
                             limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=OVEN_DAMPING,
                             armature=OVEN_ARMATURE, stiffness=_BURNER_STIFFNESS[k])  # fmt: skip
            burner.add_geom(type=manip.CYLINDER, size=(0.1, 0.01, 0), contype=0, conaffinity=0,
                            group=1, density=0.0, rgba=(0.9, 0.1, 0.0, 1))  # fmt: skip
            _couple(spec, f"knob_Joint_{k + 1}", f"burner_Joint_{k + 1}", KNOB_PER_BURNER)

        hood = desk.add_body(name="hoodroot", pos=HOOD_POS)
        pos, half = _HOOD_BLOCK
        manip.add_fixture(spec, hood, name="hood_block", pos=pos, size=half, rgba=_BLACK)
        switch = hood.add_body(name="lightswitchroot", pos=LIGHTSWITCH_POS)
        manip.set_inertial(switch, LIGHTSWITCH_MASS, (0.001,) * 3, _SWITCH_IPOS)
        switch.add_joint(name="lightswitch_joint", axis=(0, 0, 1), range=LIGHTSWITCH_RANGE,
                         limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=OVEN_DAMPING,
                         armature=OVEN_ARMATURE, frictionloss=LIGHT_FRICTIONLOSS)  # fmt: skip
        cpos, ceuler, radius, chalf = _SWITCH_CAPSULE
        _moving_geom(switch, manip.CAPSULE, pos=cpos, quat=_quat(ceuler), size=(radius, chalf, 0),
                     rgba=_METAL)  # fmt: skip
        light = hood.add_body(name="lightblock_hinge", pos=LIGHT_POS)
        manip.set_inertial(light, LIGHT_MASS, (0.001,) * 3, _SWITCH_IPOS)
        light.add_joint(name="light_joint", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=(0, 0, -1),
                        range=LIGHT_RANGE, limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                        damping=OVEN_DAMPING, armature=OVEN_ARMATURE,
                        frictionloss=LIGHT_FRICTIONLOSS)  # fmt: skip
        ppos, phalf = _LIGHT_PLATE
        light.add_geom(type=manip.BOX, pos=ppos, size=phalf, contype=0, conaffinity=0, group=1,
                       density=0.0, rgba=(0.1, 0.1, 0.1, 1))  # fmt: skip
        _couple(spec, "lightswitch_joint", "light_joint", SWITCH_PER_LIGHT)

    def _build_slide_cabinet(self, spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
        cabinet = desk.add_body(name="slidecabinet", pos=SLIDE_CABINET_POS)
        for k, (pos, half) in enumerate(_SLIDE_SHELL):
            manip.add_fixture(spec, cabinet, name=f"slide_shell_{k}", pos=pos, size=half,
                              rgba=_WOOD)  # fmt: skip
        door = cabinet.add_body(name="slidelink", pos=SLIDE_DOOR_POS)
        door.add_joint(name="slidedoor_joint", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=(1, 0, 0),
                       range=SLIDE_RANGE, **_CABINET_JOINT)  # fmt: skip
        _door(door, _SLIDE_PANEL, _SLIDE_HANDLE)

    def _build_hinge_cabinet(self, spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
        cabinet = desk.add_body(name="hingecab", pos=HINGE_CABINET_POS)
        for k, (pos, half) in enumerate(_HINGE_SHELL):
            manip.add_fixture(spec, cabinet, name=f"hinge_shell_{k}", pos=pos, size=half,
                              rgba=_WOOD)  # fmt: skip
        for name, joint, pos, lo_hi, panel_x, handle_x in _HINGE_DOORS:
            door = cabinet.add_body(name=name, pos=pos)
            door.add_joint(name=joint, axis=(0, 0, 1), range=lo_hi, **_CABINET_JOINT)
            _door(door, *_hinge_door(panel_x, handle_x))

    def _build_microwave(self, spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
        micro = desk.add_body(name="microroot", pos=MICROWAVE_POS,
                              quat=_quat((0.0, 0.0, MICROWAVE_YAW)))  # fmt: skip
        for k, (pos, half) in enumerate(_MICROWAVE_SHELL):
            manip.add_fixture(spec, micro, name=f"micro_shell_{k}", pos=pos, size=half,
                              rgba=(0.2, 0.2, 0.2, 1))  # fmt: skip
        door = micro.add_body(name="microdoorroot", pos=MICRO_DOOR_POS)
        door.add_joint(name="microjoint", axis=(0, 0, 1), range=MICRO_RANGE, **_CABINET_JOINT)
        (pos, half), mass = _MICRO_PANEL
        _moving_geom(door, manip.BOX, name="micro_door", pos=pos, size=half, mass=mass,
                     rgba=(0.3, 0.3, 0.3, 1))  # fmt: skip
        for k, (pos, axis, radius, half_len, mass) in enumerate(_MICRO_HANDLE):
            _moving_geom(door, manip.CAPSULE, name=f"micro_handle_{k}", pos=pos,
                         quat=_AXIS_QUAT[axis], size=(radius, half_len, 0), mass=mass,
                         rgba=_METAL)  # fmt: skip

    def bind(self, model: mujoco.MjModel, robot) -> None:
        adr = manip.free_joint_adr(model, "free_kettle")[0]
        if adr != N_ROBOT_QPOS + 14 or model.nq != N_ROBOT_QPOS + N_OBJECT_QPOS:
            raise ValueError(f"kitchen qpos layout broken: kettle at {adr}, nq {model.nq}")

    def init(self, key: jax.Array, qpos: jax.Array):
        return qpos, kitchen_init_state(qpos[N_ROBOT_QPOS:])

    def reset_ops(self) -> list[dict]:
        return []  # init only starts the task state; the key is unused

    def evaluate(self, robot, data: mjx.Data, state):
        reward, state, terms = kitchen_reward(data.qpos[N_ROBOT_QPOS:], state, self.strict_order)
        return reward, state["next"] >= N_SUBTASKS, state, terms

    def extra_obs(self, robot, data: mjx.Data, state) -> jax.Array:
        """[21] the object qpos."""
        return data.qpos[N_ROBOT_QPOS:]


def _moving_geom(body: mujoco.MjsBody, gtype: mujoco.mjtGeom, **kwargs) -> mujoco.MjsGeom:
    """A collider of a moving part (knob, switch, door, handle): touches the hand colliders
    (their conaffinity HANDS) and the kettle (its conaffinity FIXTURE)."""
    kwargs.setdefault("density", 0.0)
    return body.add_geom(type=gtype, contype=manip.HANDS | manip.FIXTURE, conaffinity=0, group=3,
                         **kwargs)  # fmt: skip


def _door(body: mujoco.MjsBody, panel: tuple[Box, float], bars: tuple[Bar, ...]) -> None:
    """A cabinet door: its panel box and its handle bars (HumanoidBench's cylinders: capsules
    of the same length here, the mass and inertia from non-colliding cylinders)."""
    (pos, half), mass = panel
    _moving_geom(body, manip.BOX, pos=pos, size=half, mass=mass, rgba=_WOOD)
    for pos, axis, radius, half_len, mass in bars:
        quat = _AXIS_QUAT[axis]
        body.add_geom(type=manip.CYLINDER, pos=pos, quat=quat, size=(radius, half_len, 0),
                      mass=mass, contype=0, conaffinity=0, group=1, rgba=_METAL)  # fmt: skip
        _moving_geom(body, manip.CAPSULE, pos=pos, quat=quat, size=(radius, half_len - radius, 0),
                     rgba=_METAL)  # fmt: skip


def _couple(spec: mujoco.MjSpec, joint1: str, joint2: str, ratio: float) -> None:
    """Joint equality joint1 = ratio * joint2 (HumanoidBench's polycoef "0 ratio 0 0 0")."""
    spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                      name1=joint1, name2=joint2,
                      data=[0.0, ratio, 0.0, 0.0, 0.0] + [0.0] * 7)  # fmt: skip
