"""Stair and slide: walk at 1 m/s over step pyramids or ramps (HumanoidBench §3).

Both scenes are built from boxes. The stair pyramids are cut into non-overlapping treads (the
same solid as HumanoidBench's stacked layers) and each triangular slide prism into an up and a
down box whose top faces are the prism's two slopes, so MJX's nearest-pair broad phase
(`max_geom_pairs`) ranks the boxes under the feet first.
"""

from __future__ import annotations

import math

import jax
import mujoco
from mujoco import mjx

from sirl_jax.envs import rewards as R
from sirl_jax.envs.humanoid import Task
from sirl_jax.envs.task_parts import LOCOMOTION_BUDGET
from sirl_jax.envs.tasks import scene
from sirl_jax.envs.tasks.locomotion.obstacles import OBSTACLE_GROUPS, obstacle_colliders


def climb_reward(
    head_z: jax.Array,
    left_foot_z: jax.Array,
    right_foot_z: jax.Array,
    zz: jax.Array,
    force: jax.Array,
    v_com: jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """HumanoidBench Stair / Slide: small_control * standing_rel * upright(0.5) * move(1).

    standing_rel = tol(head_z - lfoot_z, (1.2, inf), 0.45)
                 * tol(head_z - rfoot_z, (1.2, inf), 0.45).
    """
    standing = R.tolerance(head_z - left_foot_z, (1.2, math.inf), margin=0.45) * R.tolerance(
        head_z - right_foot_z, (1.2, math.inf), margin=0.45
    )
    upright = R.upright(zz, 0.5)
    small_control = R.small_control(force)
    move = R.move(v_com[0], R.WALK_SPEED)
    reward = small_control * standing * upright * move
    terms = {"standing": standing, "upright": upright, "small_control": small_control, "move": move}
    return reward, terms


STAIR_CENTRES = (3.2, 9.2, 15.2, 21.2)
STAIR_RISE, STAIR_TREAD, STAIR_STEPS = 0.18, 0.6, 5


def stair_treads(centre: float) -> list[tuple[float, float]]:
    """(x centre, height) of the 9 treads (0.6 m deep, 10 m wide) of one pyramid: 4 steps up,
    the 0.9 m top, 4 steps down."""
    out = []
    for k in range(STAIR_STEPS):
        height = STAIR_RISE * (k + 1)
        offset = STAIR_TREAD * (STAIR_STEPS - 1 - k)
        out.append((centre - offset, height))
        if offset > 0:
            out.append((centre + offset, height))
    return out


def slide_boxes(x0: float, half_thickness: float = 0.25) -> list[tuple[tuple, tuple, tuple]]:
    """(pos, size, quat) of the up and down boxes of one ramp that starts at x0: it rises 1.75 m
    over 5 m and falls over the next 5 m (HumanoidBench's 6-vertex prism), 10 m wide."""
    rise, run = 1.75, 5.0
    theta = math.atan2(rise, run)
    half_len = math.hypot(rise, run) / 2
    s, c = math.sin(theta), math.cos(theta)
    out = []
    for sign, mid_x in ((1.0, x0 + run / 2), (-1.0, x0 + 1.5 * run)):
        # Top face through the slope's midpoint; the box centre lies half a thickness below it.
        normal = (-sign * s, c)
        pos = (mid_x - half_thickness * normal[0], 0.0, rise / 2 - half_thickness * normal[1])
        phi = -sign * theta  # rotation about +y that tilts the box's x axis onto the slope
        quat = (math.cos(phi / 2), 0.0, math.sin(phi / 2), 0.0)
        out.append((pos, (half_len, 5.0, half_thickness), quat))
    return out


class ClimbTask(Task):
    """Stair or slide; terminates when the torso zz < 0.1."""

    max_contact_points = LOCOMOTION_BUDGET

    metric_names = ("standing", "upright", "small_control", "move")

    def __init__(self, name: str):
        if name not in ("stair", "slide"):
            raise ValueError(f"unknown climbing task {name!r}; allowed: 'stair', 'slide'")
        self.name = name

    def build(self, spec: mujoco.MjSpec, variant: str) -> None:
        groups = obstacle_colliders(variant)  # the hands: wrist and palm boxes only
        # treads and ramps: every collider the obstacle tasks use (HumanoidBench's palms,
        # ankles, thighs and shins touch its steps and slopes)
        low = scene.set_contact_bits(spec, groups, OBSTACLE_GROUPS)
        body = scene.set_contact_bits(spec, groups, ("body",))
        rgba = (0.8, 0.8, 0.83, 1)
        if self.name == "stair":
            for centre in STAIR_CENTRES:
                for x, h in stair_treads(centre):
                    scene.add_static_geom(spec, low, pos=(x, 0, h / 2), size=(0.3, 5.0, h / 2),
                                          rgba=rgba)
            walls = (
                ((13.5, -5.05, 2.0), (15.5, 0.1, 2.0)),
                ((13.5, 5.05, 2.0), (15.5, 0.1, 2.0)),
                ((-2.1, 0.0, 2.0), (0.1, 7.25, 2.0)),
            )
        else:
            for k in range(9):
                for pos, size, quat in slide_boxes(0.3 + 10.0 * k):
                    scene.add_static_geom(spec, low, pos=pos, size=size, quat=quat, rgba=rgba)
            walls = (
                ((48.85, -5.15, 4.0), (53.0, 0.15, 4.0)),
                ((48.85, 5.15, 4.0), (53.0, 0.15, 4.0)),
                ((-4.0, 0.0, 4.0), (0.15, 5.15, 4.0)),
            )
        for pos, size in walls:
            scene.add_static_geom(spec, body, pos=pos, size=size, rgba=(0.5, 0.5, 0.5, 0.2))
        # Per collision function: the 3 wall pairs (ranked first: long walls have huge bounding
        # spheres), then the treads/ramps nearest the robot. Slide needs 12: at 8, MJX skipped
        # a touching ramp pair in 2-3% of random-action states (`pair_cap`), at 12 in none.
        scene.set_max_geom_pairs(spec, 8 if self.name == "stair" else 12)

    def evaluate(self, robot, data: mjx.Data, task_state):
        reward, terms = climb_reward(
            robot.head_height(data),
            robot.site_pos(data, "left_foot")[2],
            robot.site_pos(data, "right_foot")[2],
            robot.torso_upright(data),
            robot.actuator_forces(data),
            robot.com_velocity(data),
        )
        return reward, robot.torso_upright(data) < 0.1, task_state, terms
