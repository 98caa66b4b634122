"""The exact overlap query (`sirl_jax/envs/overlap.py`) against MuJoCo C's collision.

Every supported type pair is posed at random near contact; MuJoCo C's `mj_forward` on a
two-geom model says whether a penetrating contact exists, and the query must agree.
"""

import itertools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from sirl_jax.envs import overlap

pytestmark = pytest.mark.timeout(300)

_TYPES = {"sphere": "0.06", "capsule": "0.05 0.15", "box": "0.08 0.05 0.12"}


def _model(t1: str, t2: str) -> mujoco.MjModel:
    xml = f"""<mujoco><option><flag gravity="disable"/></option><worldbody>
      <body name="a"><freejoint/><geom type="{t1}" size="{_TYPES[t1]}"/></body>
      <body name="b"><freejoint/><geom type="{t2}" size="{_TYPES[t2]}"/></body>
    </worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def _random_poses(rng, n: int, reach: float) -> np.ndarray:
    quat = rng.normal(size=(n, 2, 4))
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    pos = np.zeros((n, 2, 3))
    pos[:, 1] = rng.uniform(-1, 1, (n, 3)) * reach  # reach: the sum of bounding radii
    return np.concatenate([pos, quat], -1).reshape(n, 14)


@pytest.mark.parametrize(
    "t1,t2", list(itertools.combinations_with_replacement(["sphere", "capsule", "box"], 2))
)
def test_query_agrees_with_mujoco_c(t1, t2):
    m = _model(t1, t2)
    query = overlap.PairQuery(m, [0], [1])
    hit = jax.jit(lambda xpos, xmat: query.any(_DataArrays(xpos, xmat)))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    reach = float(m.geom_rbound.sum())
    poses = np.concatenate([_random_poses(rng, 1500, reach), _random_poses(rng, 1500, reach / 2)])
    cases = {True: [], False: []}  # 200 touching and 200 free poses, by MuJoCo C
    for q in poses:
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        dist = min((d.contact[i].dist for i in range(d.ncon)), default=np.inf)
        if len(cases[dist < 0]) < 200:
            cases[dist < 0].append((d.geom_xpos.copy(), d.geom_xmat.copy(), dist))
    assert min(len(v) for v in cases.values()) == 200
    wrong = []
    for c_hit, rows in cases.items():
        for xpos, xmat, dist in rows:
            if bool(hit(jnp.asarray(xpos, jnp.float32), jnp.asarray(xmat, jnp.float32))) != c_hit:
                wrong.append(float(dist))
    # Disagreements only at grazing contact (C's own convex tolerance), never deep.
    assert len(wrong) <= 2 and all(abs(x) < 2e-3 for x in wrong), wrong


class _DataArrays:
    def __init__(self, xpos, xmat):
        self.geom_xpos, self.geom_xmat = xpos, xmat.reshape(-1, 3, 3)


def test_candidate_cap_ranks_by_the_bound():
    """With a cap of 1 candidate, the nearest obstacle is the one tested: a touching box among
    far ones is found, and the candidate count reports the pairs the bound kept."""
    xml = """<mujoco><worldbody>
      <geom name="far1" type="box" size="0.5 0.5 0.5" pos="5 0 0"/>
      <geom name="near" type="box" size="0.5 0.5 0.5" pos="0 0.55 0"/>
      <geom name="far2" type="box" size="0.5 0.5 0.5" pos="-5 0 0"/>
      <body><freejoint/><geom name="cap" type="capsule" size="0.06 0.2"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    query = overlap.PairQuery(m, [3], [0, 1, 2], max_candidates=1)
    data = _DataArrays(jnp.asarray(d.geom_xpos), jnp.asarray(d.geom_xmat))
    assert bool(query.any(data))  # capsule radius 0.06 reaches y = 0.05 < the near box's 0.05
    assert int(query.candidates(data)) == 1


def test_below_floor_by_type():
    xml = """<mujoco><worldbody>
      <body pos="0 0 0.051" euler="90 0 0"><geom type="capsule" size="0.05 0.2"/></body>
      <body pos="0 0 0.3"><geom type="sphere" size="0.29"/></body>
      <body pos="0 0 0.1" euler="0 45 0"><geom type="box" size="0.1 0.1 0.1"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    data = _DataArrays(jnp.asarray(d.geom_xpos), jnp.asarray(d.geom_xmat))
    # capsule lying flat: lowest z = 0.051 - 0.05 = 0.001; sphere: 0.01 above;
    # box rotated 45 deg about y: lowest z = 0.1 - 0.1 * sqrt(2) < 0.
    assert not bool(overlap.below_floor(m, [0, 1], data))
    assert bool(overlap.below_floor(m, [2], data))
    with pytest.raises(ValueError, match="max_candidates must be >= 1"):
        overlap.PairQuery(m, [0], [1], max_candidates=0)
