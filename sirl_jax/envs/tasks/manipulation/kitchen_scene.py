"""HumanoidBench's kitchen scene, built from primitives with `MjSpec` (its kitchen XML does not
compile under MuJoCo 4.0); the task, its reward and its keyframe are in `kitchen.py`.

Frames and numbers are HumanoidBench's: the furniture hangs off a desk frame at (-0.1, 0.75, 0);
each part below is given in its own frame, as HumanoidBench nests them. Scene deviations are
listed in `KitchenTask`'s docstring.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from sirl_jax.envs.tasks import scene

# -- the scene, HumanoidBench's numbers -------------------------------------------------------
DESK_POS = (-0.1, 0.75, 0.0)
KETTLE_POS = (-0.269, 0.35, 0.994)  # on the bottom left burner; its keyframe position
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
# m: the counters and the oven block, cut likewise. Whole, their 0.8-1.25 m bounding spheres
# outrank the kettle on the stove and the hands on the worktop in MJX's `max_geom_pairs` cull
# (experiments/fidelity/pair_cap.py; docs/tasks.md, "Contact sets").
FIXTURE_SEGMENT = 0.6
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


def build_kitchen(spec: mujoco.MjSpec) -> None:
    """Adds HumanoidBench's kitchen (furniture in the desk frame, the free kettle) to `spec`."""
    desk = spec.worldbody.add_body(name="desk", pos=DESK_POS)
    counters = desk.add_body(name="counters")
    for k, (pos, half) in enumerate(_COUNTERS):
        scene.add_segmented_box(counters, f"counter_{k}", pos, half, FIXTURE_SEGMENT,
                                contype=scene.FIXTURE, conaffinity=0,
                                rgba=_MARBLE if pos[2] > 0.9 else _WOOD)  # fmt: skip
    _oven(spec, desk)
    walls = desk.add_body(name="backwall", pos=(0.0, 0.0, WALL_Z))
    for k, (pos, yaw, boxes) in enumerate(_WALLS):
        wall = walls.add_body(name=f"wall_{k}", pos=pos, quat=_quat((0.0, 0.0, yaw)))
        for j, (bpos, half) in enumerate(boxes):
            scene.add_segmented_box(wall, f"wall_{k}{j}", bpos, half, WALL_SEGMENT,
                                    contype=scene.FIXTURE, conaffinity=0, rgba=_WALL)
    _slide_cabinet(spec, desk)
    _hinge_cabinet(spec, desk)
    _microwave(spec, desk)
    kettle = spec.worldbody.add_body(name="kettle", pos=(*KETTLE_POS[:2], 1.0))
    kettle.add_freejoint(name="free_kettle")
    (pos, half), mass = _KETTLE_BODY
    scene.add_object_geom(kettle, name="kettle_body", type=scene.BOX, pos=pos, size=half,
                          mass=mass, rgba=(0.9, 0.9, 0.9, 1))  # fmt: skip
    for k, (pos, euler, radius, half, mass) in enumerate(_KETTLE_CAPSULES):
        scene.add_object_geom(kettle, name=f"kettle_capsule_{k}", type=scene.CAPSULE,
                              pos=pos, quat=_quat(euler), size=(radius, half, 0), mass=mass,
                              rgba=(0.6, 0.45, 0.3, 1))  # fmt: skip

def _oven(spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
    oven = desk.add_body(name="ovenroot", pos=OVEN_POS)
    pos, half = _OVEN_BLOCK
    scene.add_segmented_box(oven, "oven_block", pos, half, FIXTURE_SEGMENT,
                            contype=scene.FIXTURE, conaffinity=0, rgba=_BLACK)  # fmt: skip
    knob_quat = _quat((1.57, 0.0, 0.0))
    disc_half = _KNOB_DISC[0] * math.sqrt(math.pi) / 2  # a square of the disc's area
    for k in range(4):
        x, z = _KNOBS[k]
        knob = oven.add_body(name=f"knob {k + 1}", pos=(x, 0.22, z), quat=knob_quat)
        knob.add_joint(name=f"knob_Joint_{k + 1}", axis=(0, 0, 1), range=KNOB_RANGE,
                       limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=OVEN_DAMPING,
                       armature=OVEN_ARMATURE)  # fmt: skip
        bar_pos, bar_half = _KNOB_BAR
        _moving_geom(knob, scene.BOX, pos=bar_pos, size=bar_half, mass=KNOB_PART_MASS,
                     rgba=(0.8, 0.1, 0.1, 1))  # fmt: skip
        _moving_geom(knob, scene.BOX, pos=(0, 0, _KNOB_DISC[2]),
                     size=(disc_half, disc_half, _KNOB_DISC[1]), mass=KNOB_PART_MASS,
                     rgba=_METAL)  # fmt: skip
        bx, by = _BURNERS[k]
        burner = oven.add_body(name=f"Burner {k + 1}", pos=(bx, by, -0.02))
        scene.set_inertial(burner, BURNER_MASS, (BURNER_INERTIA,) * 3)
        burner.add_joint(name=f"burner_Joint_{k + 1}", type=mujoco.mjtJoint.mjJNT_SLIDE,
                         axis=(0, 0, -1), range=BURNER_RANGE,
                         limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=OVEN_DAMPING,
                         armature=OVEN_ARMATURE, stiffness=_BURNER_STIFFNESS[k])  # fmt: skip
        burner.add_geom(type=scene.CYLINDER, size=(0.1, 0.01, 0), contype=0, conaffinity=0,
                        group=1, density=0.0, rgba=(0.9, 0.1, 0.0, 1))  # fmt: skip
        _couple(spec, f"knob_Joint_{k + 1}", f"burner_Joint_{k + 1}", KNOB_PER_BURNER)

    hood = desk.add_body(name="hoodroot", pos=HOOD_POS)
    pos, half = _HOOD_BLOCK
    scene.add_fixture(spec, hood, name="hood_block", pos=pos, size=half, rgba=_BLACK)
    switch = hood.add_body(name="lightswitchroot", pos=LIGHTSWITCH_POS)
    scene.set_inertial(switch, LIGHTSWITCH_MASS, (0.001,) * 3, _SWITCH_IPOS)
    switch.add_joint(name="lightswitch_joint", axis=(0, 0, 1), range=LIGHTSWITCH_RANGE,
                     limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=OVEN_DAMPING,
                     armature=OVEN_ARMATURE, frictionloss=LIGHT_FRICTIONLOSS)  # fmt: skip
    cpos, ceuler, radius, chalf = _SWITCH_CAPSULE
    _moving_geom(switch, scene.CAPSULE, pos=cpos, quat=_quat(ceuler), size=(radius, chalf, 0),
                 rgba=_METAL)  # fmt: skip
    light = hood.add_body(name="lightblock_hinge", pos=LIGHT_POS)
    scene.set_inertial(light, LIGHT_MASS, (0.001,) * 3, _SWITCH_IPOS)
    light.add_joint(name="light_joint", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=(0, 0, -1),
                    range=LIGHT_RANGE, limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                    damping=OVEN_DAMPING, armature=OVEN_ARMATURE,
                    frictionloss=LIGHT_FRICTIONLOSS)  # fmt: skip
    ppos, phalf = _LIGHT_PLATE
    light.add_geom(type=scene.BOX, pos=ppos, size=phalf, contype=0, conaffinity=0, group=1,
                   density=0.0, rgba=(0.1, 0.1, 0.1, 1))  # fmt: skip
    _couple(spec, "lightswitch_joint", "light_joint", SWITCH_PER_LIGHT)

def _slide_cabinet(spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
    cabinet = desk.add_body(name="slidecabinet", pos=SLIDE_CABINET_POS)
    for k, (pos, half) in enumerate(_SLIDE_SHELL):
        scene.add_fixture(spec, cabinet, name=f"slide_shell_{k}", pos=pos, size=half,
                          rgba=_WOOD)  # fmt: skip
    door = cabinet.add_body(name="slidelink", pos=SLIDE_DOOR_POS)
    door.add_joint(name="slidedoor_joint", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=(1, 0, 0),
                   range=SLIDE_RANGE, **_CABINET_JOINT)  # fmt: skip
    _door(door, _SLIDE_PANEL, _SLIDE_HANDLE)

def _hinge_cabinet(spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
    cabinet = desk.add_body(name="hingecab", pos=HINGE_CABINET_POS)
    for k, (pos, half) in enumerate(_HINGE_SHELL):
        scene.add_fixture(spec, cabinet, name=f"hinge_shell_{k}", pos=pos, size=half,
                          rgba=_WOOD)  # fmt: skip
    for name, joint, pos, lo_hi, panel_x, handle_x in _HINGE_DOORS:
        door = cabinet.add_body(name=name, pos=pos)
        door.add_joint(name=joint, axis=(0, 0, 1), range=lo_hi, **_CABINET_JOINT)
        _door(door, *_hinge_door(panel_x, handle_x))

def _microwave(spec: mujoco.MjSpec, desk: mujoco.MjsBody) -> None:
    micro = desk.add_body(name="microroot", pos=MICROWAVE_POS,
                          quat=_quat((0.0, 0.0, MICROWAVE_YAW)))  # fmt: skip
    for k, (pos, half) in enumerate(_MICROWAVE_SHELL):
        scene.add_fixture(spec, micro, name=f"micro_shell_{k}", pos=pos, size=half,
                          rgba=(0.2, 0.2, 0.2, 1))  # fmt: skip
    door = micro.add_body(name="microdoorroot", pos=MICRO_DOOR_POS)
    door.add_joint(name="microjoint", axis=(0, 0, 1), range=MICRO_RANGE, **_CABINET_JOINT)
    (pos, half), mass = _MICRO_PANEL
    _moving_geom(door, scene.BOX, name="micro_door", pos=pos, size=half, mass=mass,
                 rgba=(0.3, 0.3, 0.3, 1))  # fmt: skip
    for k, (pos, axis, radius, half_len, mass) in enumerate(_MICRO_HANDLE):
        _moving_geom(door, scene.CAPSULE, name=f"micro_handle_{k}", pos=pos,
                     quat=_AXIS_QUAT[axis], size=(radius, half_len, 0), mass=mass,
                     rgba=_METAL)  # fmt: skip


def _moving_geom(body: mujoco.MjsBody, gtype: mujoco.mjtGeom, **kwargs) -> mujoco.MjsGeom:
    """A collider of a moving part (knob, switch, door, handle): touches the hand colliders
    (their conaffinity HANDS) and the kettle (its conaffinity FIXTURE)."""
    kwargs.setdefault("density", 0.0)
    return body.add_geom(type=gtype, contype=scene.HANDS | scene.FIXTURE, conaffinity=0, group=3,
                         **kwargs)  # fmt: skip


def _door(body: mujoco.MjsBody, panel: tuple[Box, float], bars: tuple[Bar, ...]) -> None:
    """A cabinet door: its panel box and its handle bars (HumanoidBench's cylinders: capsules
    of the same length here, the mass and inertia from non-colliding cylinders)."""
    (pos, half), mass = panel
    _moving_geom(body, scene.BOX, pos=pos, size=half, mass=mass, rgba=_WOOD)
    for pos, axis, radius, half_len, mass in bars:
        quat = _AXIS_QUAT[axis]
        body.add_geom(type=scene.CYLINDER, pos=pos, quat=quat, size=(radius, half_len, 0),
                      mass=mass, contype=0, conaffinity=0, group=1, rgba=_METAL)  # fmt: skip
        _moving_geom(body, scene.CAPSULE, pos=pos, quat=quat, size=(radius, half_len - radius, 0),
                     rgba=_METAL)  # fmt: skip


def _couple(spec: mujoco.MjSpec, joint1: str, joint2: str, ratio: float) -> None:
    """Joint equality joint1 = ratio * joint2 (HumanoidBench's polycoef "0 ratio 0 0 0")."""
    spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                      name1=joint1, name2=joint2,
                      data=[0.0, ratio, 0.0, 0.0, 0.0] + [0.0] * 7)  # fmt: skip
