"""hb_parity's account of a disagreeing state (experiments/fidelity/hb_parity.py): the deepest
contact of each class, and `OurGap`, how far apart our colliders are where HumanoidBench's
touch. On a constructed model (MuJoCo C only) whose distances are worked out by hand; the
model stands in for both sides, as the two share body and geom names."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from experiments.fidelity.hb_contacts import GAP_MAX, OurGap, deepest, tables
from experiments.fidelity.hb_ours import merge

XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="table" type="box" pos="0.6 0 0.12" size="0.1 0.1 0.1" contype="1" conaffinity="1"/>
    <geom name="far_wall" type="box" pos="0 3 0.5" size="0.1 0.1 0.5" contype="1" conaffinity="1"/>
    <body name="pelvis" pos="0 0 0.5">
      <freejoint/>
      <geom name="torso" type="sphere" size="0.1"/>
      <body name="left_hand" pos="0.3 0 0">
        <geom name="left_palm" type="sphere" size="0.05"/>
      </body>
      <body name="right_hand" pos="-0.3 0 0">
        <geom name="right_palm" type="sphere" size="0.05" contype="2" conaffinity="2"/>
      </body>
    </body>
    <body name="object" pos="0 -1 0.05">
      <freejoint/>
      <geom name="box" type="box" size="0.05 0.05 0.05"/>
    </body>
  </worldbody>
</mujoco>
"""
PELVIS_Z = 0.12  # the torso sphere (r 0.1) 2 cm above the floor


@pytest.fixture(scope="module")
def model():
    m = mujoco.MjModel.from_xml_string(XML)
    qpos = m.qpos0.copy()
    qpos[2] = PELVIS_Z
    return m, qpos


def _g(m, name: str) -> int:
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)


def test_gap_is_the_distance_between_our_colliders(model):
    m, qpos = model
    gap = OurGap(m, tables(m))
    # torso sphere over the floor: 0.12 - 0.1
    assert gap(qpos, [(_g(m, "torso"), _g(m, "floor"))]) == pytest.approx(0.02, abs=1e-9)
    # left palm (centre x 0.3, r 0.05) to the table's face at x 0.5: 0.15
    assert gap(qpos, [(_g(m, "left_palm"), _g(m, "table"))]) == pytest.approx(0.15, abs=1e-9)
    # the state's gap is the nearest of its contacts
    both = [(_g(m, "left_palm"), _g(m, "table")), (_g(m, "torso"), _g(m, "floor"))]
    assert gap(qpos, both) == pytest.approx(0.02, abs=1e-9)
    # farther than GAP_MAX reads GAP_MAX
    assert gap(qpos, [(_g(m, "torso"), _g(m, "far_wall"))]) == pytest.approx(GAP_MAX)


def test_a_pair_our_bits_leave_out_has_no_gap(model):
    m, qpos = model
    # right palm: contype 2 / conaffinity 2 against the table's 1 / 1: never collides
    assert OurGap(m, tables(m))(qpos, [(_g(m, "right_palm"), _g(m, "table"))]) is None


def test_unknown_fixture_names_fall_back_to_every_fixture(model):
    m, qpos = model
    hb = tables(m)
    hb["geom_name"] = np.array([("hb_" + n) if n == "table" else n for n in hb["geom_name"]])
    gap = OurGap(m, hb)
    # HumanoidBench's "hb_table" is none of ours: the nearest of our fixtures (table, far wall)
    assert gap(qpos, [(_g(m, "left_palm"), _g(m, "table"))]) == pytest.approx(0.15, abs=1e-9)


def test_deepest_contact_per_class(model):
    m, _ = model
    t = tables(m)
    floor, torso, palm, table, box = (
        _g(m, n) for n in ("floor", "torso", "left_palm", "table", "box")
    )
    state = [0, 0, 1, 2]
    g1 = [floor, torso, palm, box]
    g2 = [torso, floor, table, floor]
    dist = [-0.004, -0.011, -0.002, -0.001]
    out = deepest(t, state, g1, g2, dist, 3)
    np.testing.assert_allclose(out["robot-floor"], [0.011, np.nan, np.nan])
    np.testing.assert_allclose(out["robot-static"], [np.nan, 0.002, np.nan])
    np.testing.assert_allclose(out["object-floor"], [np.nan, np.nan, 0.001])
    assert np.isnan(out["hand-object"]).all()


def test_a_failed_rerun_keeps_the_measured_row():
    results = {"a": {"states": 500}, "b": {"error": "old"}}
    assert not merge(results, "a", {"error": "torch missing"})
    assert results["a"] == {"states": 500}
    assert merge(results, "b", {"error": "new"}) and results["b"] == {"error": "new"}
    assert merge(results, "c", {"error": "x"}) and merge(results, "a", {"states": 400})
    assert results["a"] == {"states": 400}
