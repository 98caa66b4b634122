"""Contacts of a task state on either model, for hb_parity: each geom's role (robot, hand,
object, floor, static) from its body, the contact classes of the parity bars, our MuJoCo C
contacts, and how far apart our colliders are where HumanoidBench's touch (`OurGap`)."""

from __future__ import annotations

import collections
import itertools

import mujoco
import numpy as np

from experiments.fidelity.hb_side import model_tables

ROBOT_ROOT, HANDS, FLOOR = "pelvis", ("left_hand", "right_hand"), "floor"


CLASSES = ("robot-static", "hand-object", "object-object",
           "robot-floor", "robot-object", "object-static", "object-floor")  # fmt: skip


BAR_CLASSES = ("robot-static", "hand-object", "object-object")


def tables(m: mujoco.MjModel) -> dict[str, np.ndarray]:
    """The model tables `roles` reads, as hb_side.py writes them for HumanoidBench's model."""
    return model_tables(mujoco, m)


def roles(t: dict[str, np.ndarray]) -> tuple[list[str], list[str]]:
    """([ngeom] role, [ngeom] label): role in {hand, robot, object, floor, static}; label =
    the body name, or the geom name for a geom welded to the world."""
    names = [str(x) for x in t["body_name"]]
    parent = t["body_parent"]

    def under(b: int, roots: set[int]) -> bool:
        while b > 0:
            if b in roots:
                return True
            b = int(parent[b])
        return False

    robot = {names.index(ROBOT_ROOT)}
    hands = {names.index(h) for h in HANDS}
    objects = {b for b in range(len(names)) if t["body_free"][b] and b not in robot}
    out_role, out_label = [], []
    for g, (gname, b) in enumerate(zip(t["geom_name"], t["geom_body"], strict=True)):
        b, gname = int(b), str(gname)
        if under(b, hands):
            role = "hand"
        elif under(b, robot):
            role = "robot"
        elif under(b, objects):
            role = "object"
        elif gname == FLOOR or (b == 0 and t["geom_type"][g] == mujoco.mjtGeom.mjGEOM_PLANE):
            role = "floor"
        else:
            role = "static"
        out_role.append(role)
        welded = int(t["body_weldid"][b]) == 0
        out_label.append((gname or f"geom{g}") if welded else names[b])
    return out_role, out_label


def contact_class(r1: str, r2: str) -> str | None:
    a, b = sorted((r1, r2))
    pair = {a, b}
    if pair == {"hand", "object"}:
        return "hand-object"
    if a == b == "object":
        return "object-object"
    if "object" in pair:
        other = (pair - {"object"}).pop()
        return {"robot": "robot-object", "static": "object-static", "floor": "object-floor"}.get(
            other
        )
    if pair & {"hand", "robot"}:
        other = pair - {"hand", "robot"}
        if other == {"static"}:
            return "robot-static"
        if other == {"floor"}:
            return "robot-floor"
    return None  # robot-robot, static-floor, ...


def classify(t, state, g1, g2, n):
    """({class: [n] bool fired}, {class: [n] Counter of label pairs})."""
    role, label = roles(t)
    fired = {c: np.zeros(n, bool) for c in CLASSES}
    pairs = {c: [collections.Counter() for _ in range(n)] for c in CLASSES}
    for i, a, b in zip(state, g1, g2, strict=True):
        c = contact_class(role[a], role[b])
        if c is None:
            continue
        fired[c][i] = True
        pairs[c][i]["|".join(sorted((label[a], label[b])))] += 1
    return fired, pairs


def our_contacts(m: mujoco.MjModel, qpos, qvel, ctrl):
    """(state, geom1, geom2, dist) of every contact of every state, MuJoCo C on our model."""
    d = mujoco.MjData(m)
    state, g1, g2, dist = [], [], [], []
    for i in range(len(qpos)):
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos[i], qvel[i], ctrl[i]
        mujoco.mj_forward(m, d)
        for c in d.contact[: d.ncon]:
            state.append(i)
            g1.append(int(c.geom1))
            g2.append(int(c.geom2))
            dist.append(float(c.dist))
    return state, g1, g2, dist


GAP_MAX = 0.25
"""Our gap is measured up to this many metres (`mj_geomDistance`'s distmax)."""


def deepest(t, state, g1, g2, dist, n) -> dict[str, np.ndarray]:
    """{class: [n] deepest penetration (m, >= 0; nan where the class has no contact)}."""
    role, _ = roles(t)
    out = {c: np.full(n, np.nan) for c in CLASSES}
    for i, a, b, x in zip(state, g1, g2, dist, strict=True):
        c = contact_class(role[a], role[b])
        if c is not None:
            out[c][i] = np.fmax(out[c][i], -x)
    return out


class OurGap:
    """Where HumanoidBench's model touches and ours does not: how far apart our colliders are.

    HumanoidBench's contact (geom A, geom B) maps to our geoms by body: a robot or hand geom to
    our geoms on the body of the same name, an object geom to our object of the same body name,
    the floor to our floor, a fixture or obstacle geom to our geom of the same name, else to
    every fixture or obstacle geom of ours. Of those pairs, only the ones our contact bits let
    collide count (contype / conaffinity; parent-child and welded pairs are already apart in
    the robot-versus-world classes measured here). Gap = the smallest `mj_geomDistance` among
    them; None where no pair may collide (our contact set leaves the pair out)."""

    def __init__(self, m: mujoco.MjModel, hb_tables: dict[str, np.ndarray]):
        self.m, self.d = m, mujoco.MjData(m)
        ours = tables(m)
        self.role, _ = roles(ours)
        self.hb_role, _ = roles(hb_tables)
        body = [str(ours["body_name"][b]) for b in ours["geom_body"]]
        self.by_body = collections.defaultdict(list)
        self.by_name = {str(n): g for g, n in enumerate(ours["geom_name"]) if str(n)}
        self.by_role = collections.defaultdict(list)
        for g in range(m.ngeom):
            if m.geom_contype[g] or m.geom_conaffinity[g]:
                self.by_body[body[g]].append(g)
                self.by_role[self.role[g]].append(g)
        self.hb_body = [str(hb_tables["body_name"][b]) for b in hb_tables["geom_body"]]
        self.hb_name = [str(x) for x in hb_tables["geom_name"]]

    def _ours(self, g: int) -> list[int]:
        role = self.hb_role[g]
        if role in ("robot", "hand", "object"):
            mine = self.by_body.get(self.hb_body[g], [])
            return mine if mine or role != "object" else self.by_role["object"]
        mine = self.by_name.get(self.hb_name[g])
        if mine is not None and self.role[mine] == role:
            return [mine]
        return self.by_role[role]

    def __call__(self, qpos: np.ndarray, hb_pairs: list[tuple[int, int]]) -> float | None:
        m, d = self.m, self.d
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        best = None
        for a, b in hb_pairs:
            for x, y in itertools.product(self._ours(a), self._ours(b)):
                if not (m.geom_contype[x] & m.geom_conaffinity[y]
                        or m.geom_contype[y] & m.geom_conaffinity[x]):  # fmt: skip
                    continue
                gap = mujoco.mj_geomDistance(m, d, x, y, GAP_MAX, None)
                best = gap if best is None else min(best, gap)
        return best


def mm_stats(x) -> dict:
    a = np.asarray([v for v in x if v is not None and np.isfinite(v)]) * 1000.0
    if not len(a):
        return {}
    return {"p50": round(float(np.median(a)), 1), "p95": round(float(np.percentile(a, 95)), 1),
            "max": round(float(a.max()), 1)}  # fmt: skip
