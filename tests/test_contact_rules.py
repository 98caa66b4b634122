"""The obstacle penalties on constructed states: a hand, an arm and a foot pushed 1.4 cm into a
hurdle barrier, a maze block and a pole each trigger the 0.1 discount, as in HumanoidBench
(which counts a contact of any robot geom), and the obstacle moved away does not.

Each state is built in MuJoCo C: the robot in a pose (keyframe, or with one joint moved), the
obstacle geom moved so that its surface lies 1.4 cm inside the part's extreme point along a
direction. MuJoCo C's `mj_geomDistance` confirms the penetration and that only geoms of the
part's group touch, so the discount can come from that part alone. Before this rule the hurdle
barriers touched only the pelvis, torso and head, and no obstacle touched the hands.
"""

import copy

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx
from shapes import support

from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.envs.tasks.locomotion.obstacles import (
    WALL_DISCOUNT,
    HurdleTask,
    MazeTask,
    PoleTask,
)
from sirl_jax.envs.tasks.scene import add_segmented_box

pytestmark = pytest.mark.timeout(600)

DEPTH = 0.014
ARM_OUT = {"left_shoulder_roll": 1.5}
# task -> (obstacle geom, discount metric, [(group, part geom, joint overrides, direction, shift)])
CASES = {
    "hurdle": ("behind_barrier_collision_2", "wall_collision_discount", [
        ("hands", "lh_mfdistal", {}, (1, 0, 0), (0, 0, 0)),
        ("arms", "left_forearm", {}, (0, 1, 0), (0, 0, 0.6)),
        ("feet", "left_foot", {}, (-1, 0, 0), (0, 0, -0.3)),
    ]),
    "maze": ("block_collision_00", "wall_collision_discount", [
        ("hands", "lh_mfdistal", {}, (1, 0, 0), (0, 0, 0)),
        ("arms", "left_upper_arm", {}, (0, 1, 0), (0, 0, 0.6)),
        ("feet", "left_foot", {}, (1, 0, 0), (0, 0, -0.6)),
        ("legs", "left_thigh", {}, (1, 0, 0), (0, 0, -0.3)),
    ]),
    "pole": ("pole_r1_c0", "collision_discount", [
        ("hands", "lh_mfdistal", {}, (1, 0, 0), (0, 0, 0)),
        ("arms", "left_forearm", ARM_OUT, (-1, 0, 0), (0, 0, 0)),
        ("feet", "left_foot", {"left_hip_roll": 0.4}, (1, 0, 0), (0, 0, 0)),
    ]),
}  # fmt: skip
TASKS = {"hurdle": HurdleTask, "maze": MazeTask, "pole": PoleTask}


def _support(m, d, g, u) -> float:
    """The largest u-coordinate of geom g's surface (sphere, capsule, box)."""
    return support(m.geom_type[g], m.geom_size[g], d.geom_xpos[g], d.geom_xmat[g].reshape(3, 3), u)


def construct(env, obstacle, part, joints, u, shift, depth):
    """(model with the obstacle moved, qpos, {robot geom: C signed distance < 0})."""
    m = copy.copy(env.mj_model)
    # The mid-phase trees of the world's static geoms were built for their compiled positions.
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
    d = mujoco.MjData(m)
    qpos = env.robot.keyframe_qpos.copy()
    for joint, value in joints.items():
        qpos[m.jnt_qposadr[m.joint(joint).id]] = value
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    gp, go, u = m.geom(part).id, m.geom(obstacle).id, np.asarray(u, float)
    centre = d.geom_xpos[gp] - (d.geom_xpos[gp] @ u) * u + _support(m, d, gp, u) * u + shift
    if m.geom_type[go] == mujoco.mjtGeom.mjGEOM_BOX:
        pos = centre + u * (np.abs(u) @ m.geom_size[go] - depth)
    else:  # the vertical pole capsule keeps its height
        pos = centre + u * (m.geom_size[go][0] - depth)
        pos[2] = m.geom_pos[go][2]
    m.geom_pos[go] = pos
    mujoco.mj_kinematics(m, d)
    robot = np.concatenate(list(env.robot.geom_ids.values()))
    dist = {m.geom(g).name: mujoco.mj_geomDistance(m, d, int(g), go, 0.2, None) for g in robot}
    return m, qpos, {k: v for k, v in dist.items() if v < 0}


_LINKS = {
    "feet": ("ankle",),
    "legs": ("hip_yaw", "hip_roll"),
    "arms": ("shoulder_pitch", "shoulder_roll"),
}


def _group_links(env, group) -> set[str]:
    """A group's colliders and the "links" capsules of the same limb (the ankle housing beside
    the sole, the shoulder links above the upper arm, which stand out sideways)."""
    limb = _LINKS.get(group, ())
    links = {n for n in env.robot.geom_groups["links"] if n.endswith(limb)} if limb else set()
    return set(env.robot.geom_groups[group]) | links


@pytest.fixture(scope="module", params=list(CASES))
def task(request):
    env = HumanoidEnv(TASKS[request.param](), "h1hand")
    metric = CASES[request.param][1]

    @jax.jit
    def discount(mx, qpos):
        d = mjx.kinematics(mx, mjx.make_data(mx).replace(qpos=qpos))
        _, task_state = env.task.init(jax.random.PRNGKey(0), qpos)
        _, _, _, terms = env.task.evaluate(env.robot, d, task_state)
        return terms[metric]

    return request.param, env, discount


def test_any_robot_part_triggers_the_discount(task):
    name, env, discount = task
    obstacle, _, cases = CASES[name]
    for group, part, joints, u, shift in cases:
        m, qpos, touching = construct(env, obstacle, part, joints, u, shift, DEPTH)
        assert touching[part] == pytest.approx(-DEPTH, abs=2e-3), (name, part, touching)
        assert set(touching) <= _group_links(env, group), (name, part, touching)
        value = discount(mjx.put_model(m), jnp.asarray(qpos, jnp.float32))
        assert float(value) == pytest.approx(WALL_DISCOUNT), (name, part)
        # The same obstacle 5 m further along u: nothing touches, no discount.
        m, qpos, touching = construct(env, obstacle, part, joints, u, shift, -5.0)
        assert touching == {}, (name, part, touching)
        assert float(discount(mjx.put_model(m), jnp.asarray(qpos, jnp.float32))) == 1.0


def test_thigh_inside_a_maze_block_is_a_contact(task):
    """The state MJX's own contact slots can miss: a thigh capsule 1.4 cm inside a block. MuJoCo
    C on the task model (the block collides with every robot geom) has the contact; the
    discount fires."""
    name, env, discount = task
    if name != "maze":
        pytest.skip("maze only")
    m, qpos, touching = construct(env, "block_collision_00", "left_thigh", {}, (1, 0, 0),
                                  (0, 0, -0.3), DEPTH)  # fmt: skip
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    block, thigh = m.geom("block_collision_00").id, m.geom("left_thigh").id
    pairs = {(int(c.geom1), int(c.geom2)): c.dist for c in d.contact[: d.ncon]}
    dist = pairs.get((thigh, block), pairs.get((block, thigh)))
    assert dist == pytest.approx(-DEPTH, abs=1e-3)
    value = discount(mjx.put_model(m), jnp.asarray(qpos, jnp.float32))
    assert float(value) == pytest.approx(WALL_DISCOUNT)


def test_segmented_walls_tile_the_barrier():
    """A 71 m barrier cut into 15 pieces of at most 5 m: the same solid (end to end, no gap or
    overlap, the other sizes kept), each with a bounding sphere MJX can rank."""
    spec = mujoco.MjSpec()
    names = add_segmented_box(spec.worldbody, "wall", (35.0, -4.725, 1.0), (35.5, 0.275, 1.0), 5.0,
                              along="longest", contype=1, conaffinity=0)  # fmt: skip
    # along="all" cuts every axis longer than a segment: 3 x 3 x 1 pieces named by their indices
    grid = add_segmented_box(spec.worldbody, "grid", (0.0, 0.0, 5.0), (1.0, 0.75, 0.2), 0.7)
    assert grid == [f"grid_{i}{j}0" for i in range(3) for j in range(3)]
    with pytest.raises(ValueError, match="along='diagonal' is invalid"):
        add_segmented_box(spec.worldbody, "bad", (0, 0, 0), (1, 1, 1), 0.5, along="diagonal")
    m = spec.compile()
    volume = sum(8 * np.prod(m.geom(n).size) for n in grid)
    assert volume == pytest.approx(8 * 1.0 * 0.75 * 0.2)
    assert {int(m.geom(n).group[0]) for n in grid} == {3} and m.geom(names[0]).group[0] == 3
    assert len(names) == 15 and all(m.geom(n).id >= 0 for n in names)
    lo = np.array([m.geom(n).pos[0] - m.geom(n).size[0] for n in names])
    hi = np.array([m.geom(n).pos[0] + m.geom(n).size[0] for n in names])
    assert lo[0] == pytest.approx(-0.5) and hi[-1] == pytest.approx(70.5)
    np.testing.assert_allclose(lo[1:], hi[:-1], atol=1e-9)
    for n in names:
        np.testing.assert_allclose(m.geom(n).size[1:], (0.275, 1.0))
        np.testing.assert_allclose(m.geom(n).pos[1:], (-4.725, 1.0))
    assert m.geom_rbound.max() < 2.7  # the whole barrier's would be 35.5
