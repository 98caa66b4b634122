"""experiments/fidelity/pair_cap.py: its model of MJX's `max_geom_pairs` cull is MJX's own cull,
and bookshelf's cap keeps every pair that holds its objects on the shelf at the reset pose."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from mujoco import mjx

from experiments.fidelity.pair_cap import culled_groups, ranks
from sirl_jax.envs import load

CAP = 5


def _crowd() -> mujoco.MjModel:
    """Eight free boxes of mixed sizes over three static boxes (one large, two small): 35
    box-box candidates, more than `CAP`, and sphere distances with no ties."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=(1.0, 0.6, 0.05), pos=(0, 0, 0))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=(0.1, 0.1, 0.1), pos=(1.3, 0, 0.2))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=(0.1, 0.2, 0.1), pos=(0, 0.9, 0.3))
    rng = np.random.default_rng(3)
    for _ in range(8):
        body = spec.worldbody.add_body(pos=(rng.uniform(-1.2, 1.2), rng.uniform(-0.8, 0.8),
                                            rng.uniform(0.06, 0.6)))  # fmt: skip
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=rng.uniform(0.03, 0.15, 3))
    spec.add_numeric(name="max_geom_pairs", data=[float(CAP)])
    return spec.compile()


@pytest.mark.slow  # 36 s idle: MJX's cull against pair_cap's ranking, every task's pairs
@pytest.mark.timeout(300)
def test_ranks_pick_the_pairs_mjx_collides():
    m = _crowd()
    (pairs,) = culled_groups(m).values()
    assert len(pairs) == 8 * 7 // 2 + 8 * 3 and len(pairs) > CAP
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    ours = {tuple(sorted(map(int, p))) for p in pairs[ranks(m, d, pairs) < CAP]}
    dx = mjx.forward(mjx.put_model(m), mjx.put_data(m, d))
    kept = {tuple(sorted(map(int, g))) for g in np.asarray(dx._impl.contact.geom)}
    assert len(ours) == CAP and kept == ours


def test_bookshelf_cap_keeps_every_touching_pair_at_reset():
    """At HumanoidBench's keyframe (bookshelf's reset: no noise), MuJoCo C's touching pairs all
    rank under the task's cap, in both contact sets: MJX collides every one of them."""
    for contact_set in ("hb", "reduced"):
        m = load("bookshelf_simple", contact_set=contact_set)[1].mj_model
        cap = int(m.numeric_data[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC,
                                                    "max_geom_pairs")])  # fmt: skip
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        mujoco.mj_forward(m, d)
        touch = {tuple(sorted((int(c.geom1), int(c.geom2)))) for c in d.contact[: d.ncon]}
        held = 0
        for pairs in culled_groups(m).values():
            rank = ranks(m, d, pairs)
            hit = [i for i, p in enumerate(pairs) if tuple(sorted(map(int, p))) in touch]
            assert all(rank[i] < cap for i in hit), (contact_set, sorted(rank[hit]), cap)
            held += len(hit)
        assert held >= 10, contact_set  # the books, can and headphone rest on the boards
