"""Refitted colliders for collider_fit's links: one capsule per link against HumanoidBench's hull
(`refit`), K capsules at once by a minimax Nelder-Mead fit (`multi_fit`), and K-vertex convex
mesh colliders inside HumanoidBench's hull (`greedy_hull`, `hull_fit`)."""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from experiments.fidelity.collider_geoms import G, Geom, colliders, our_colliders, posed


def _hull_points(geoms: list[Geom]) -> tuple[np.ndarray, list[np.ndarray]]:
    """(world surface points of HumanoidBench's colliders [V, 3], world plane equations of
    each collider's convex hull)."""
    verts, planes = [], []
    for g in geoms:
        verts.append(g.surface())
        if g.planes is None:
            g.planes = ConvexHull(g.local_surface).equations
        n = g.planes[:, :3] @ g.mat.T
        planes.append(np.concatenate([n, (g.planes[:, 3] - n @ g.pos)[:, None]], 1))
    return np.concatenate(verts), planes


def fit_capsule(verts: np.ndarray, planes: list[np.ndarray], covered=None, seed: int = 0):
    """(a [3], b [3], r, cost before, cost after) of the capsule minimising max(HB outside
    our colliders, it outside HB), world frame. `covered(points) -> [N]` is how far points lie
    outside the link's other colliders of ours (None: there are none), so the capsule only has
    to take what they leave. Nelder-Mead from the principal axis of the uncovered points."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    unit = rng.normal(size=(600, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    t = rng.uniform(0, 1, 600)
    sub = verts[rng.choice(len(verts), min(len(verts), 3000), replace=False)]
    others = covered(sub) if covered is not None else np.full(len(sub), np.inf)
    left = sub[others > 0.005] if (others > 0.005).sum() >= 10 else sub
    centre = left.mean(0)
    axis = np.linalg.svd(left - centre)[2][0]
    proj = (left - centre) @ axis
    radial = np.linalg.norm(left - centre - np.outer(proj, axis), axis=1)
    r0 = np.percentile(radial, 75)
    x0 = np.r_[centre + axis * (proj.min() + r0), centre + axis * (proj.max() - r0), r0]

    def cost(x):
        a, b, r = x[:3], x[3:6], abs(x[6])
        ab = b - a
        s = np.clip((sub - a) @ ab / max(ab @ ab, 1e-12), 0, 1)
        mine = np.maximum(np.linalg.norm(sub - a - s[:, None] * ab, axis=1) - r, 0)
        hb_out = np.minimum(mine, others).max()
        surf = a + t[:, None] * ab + r * unit
        out = np.min([np.maximum((surf @ p[:, :3].T + p[:, 3]).max(1), 0) for p in planes], 0)
        return max(hb_out, out.max())

    res = minimize(cost, x0, method="Nelder-Mead",
                   options={"maxiter": 6000, "xatol": 1e-4, "fatol": 1e-5})  # fmt: skip
    return res.x[:3], res.x[3:6], abs(res.x[6]), cost(x0), res.fun


def refit(hb: mujoco.MjModel, ours: mujoco.MjModel, seed: int = 0) -> list[dict]:
    """Every capsule of ours on a link HumanoidBench gives a collider: the refitted capsule in
    our body frame (fromto, radius) and its fit cost before and after (m). A capsule that
    shares its link with other colliders of ours (the ankle housing beside the sole box, the
    shoulder housings beside the torso box) is fitted to what those leave uncovered."""
    rng = np.random.default_rng(seed)
    qpos = hb.qpos0[: ours.nq].copy()
    d_hb, d_us = posed(hb, qpos), posed(ours, qpos)
    col_hb, col_us = colliders(hb), our_colliders(ours)
    out = []
    for body, ids in sorted(col_us.items()):
        if body not in col_hb or body.startswith(("lh_", "rh_")):
            continue
        hb_geoms = [Geom(hb, d_hb, g, rng) for g in col_hb[body]]
        verts, planes = _hull_points(hb_geoms)
        for g in ids:
            if ours.geom_type[g] != G.mjGEOM_CAPSULE:
                continue
            rest = [Geom(ours, d_us, k, rng) for k in ids if k != g]
            covered = (
                (lambda x, rest=rest: np.min([r.outside(x) for r in rest], 0)) if rest else None
            )
            a, b, r, before, after = fit_capsule(verts, planes, covered, seed)
            b_id = ours.body(body).id
            pos, mat = d_us.xpos[b_id], d_us.xmat[b_id].reshape(3, 3)
            local = [(p - pos) @ mat for p in (a, b)]
            out.append({"body": body, "geom": ours.geom(g).name, "radius": round(float(r), 4),
                        "fromto": [round(float(v), 4) for v in np.concatenate(local)],
                        "cost_start": float(before), "cost_fit": float(after)})  # fmt: skip
    return out


def greedy_hull(points: np.ndarray, k: int) -> np.ndarray:
    """[k, 3] vertices of an inner approximation of the convex hull of `points`: start from
    the points extreme along x, y and z, then add, one at a time, the point farthest outside
    the hull of those chosen (by its largest plane distance). Its hull lies inside the
    original, so it never adds volume ("ours out" 0); "HB out" falls as k grows."""
    hull = points[ConvexHull(points).vertices]
    if k >= len(hull):
        return hull
    chosen = sorted({int(i) for i in np.r_[hull.argmax(0), hull.argmin(0)]})
    while len(chosen) < k:
        eq = ConvexHull(hull[chosen]).equations
        chosen.append(int((hull @ eq[:, :3].T + eq[:, 3]).max(1).argmax()))
    return hull[chosen]


def hull_fit(hb: mujoco.MjModel, ours: mujoco.MjModel, body: str, ks, seed: int = 0):
    """For each k of `ks`: HumanoidBench's colliders of `body` as a k-vertex inner hull
    (`greedy_hull`), its triangle count and how far HumanoidBench's surface lies outside it (m),
    the vertices in our body frame (what a mesh collider of ours would hold)."""
    rng = np.random.default_rng(seed)
    qpos = hb.qpos0[: ours.nq].copy()
    d_hb, d_us = posed(hb, qpos), posed(ours, qpos)
    if body not in (col := colliders(hb)):
        raise SystemExit(f"error: HumanoidBench has no collider on {body!r}")
    b = ours.body(body).id
    pos, mat = d_us.xpos[b], d_us.xmat[b].reshape(3, 3)
    hb_geoms = [Geom(hb, d_hb, g, rng) for g in col[body]]
    local = (np.concatenate([g.surface() for g in hb_geoms]) - pos) @ mat
    rows = []
    for k in ks:
        verts = greedy_hull(local, k)
        hull = ConvexHull(verts)
        tri = verts[hull.simplices]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        n = 60_000
        pick = rng.choice(len(tri), n, p=area / area.sum())
        u, v = rng.uniform(size=(2, n))
        flip = u + v > 1
        u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
        t = tri[pick]
        surf = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
        outside = (local @ hull.equations[:, :3].T + hull.equations[:, 3]).max(1) > 0
        hb_out = float(cKDTree(surf).query(local[outside])[0].max()) if outside.any() else 0.0
        rows.append({"body": body, "vertices": len(verts), "triangles": len(hull.simplices),
                     "hb_out": hb_out, "ours_out": 0.0,
                     "local_vertices": np.round(verts, 5).tolist()})  # fmt: skip
    return rows


def multi_fit(hb: mujoco.MjModel, ours: mujoco.MjModel, body: str, k: int, seed: int = 0):
    """The best minimax fit of k capsules at once to HumanoidBench's colliders of `body` (m)."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    d_hb = posed(hb, hb.qpos0[: ours.nq].copy())
    if body not in (col := colliders(hb)):
        raise SystemExit(f"error: HumanoidBench has no collider on {body!r}")
    verts, planes = _hull_points([Geom(hb, d_hb, g, rng) for g in col[body]])
    sub = verts[rng.choice(len(verts), min(len(verts), 2000), replace=False)]
    unit = rng.normal(size=(400, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    t = rng.uniform(0, 1, 400)
    centre = sub.mean(0)
    axes = np.linalg.svd(sub - centre)[2]
    proj = (sub - centre) @ axes.T

    def cost(x):
        gap, out = np.full(len(sub), np.inf), 0.0
        for a, b, r in ((x[i:i + 3], x[i + 3:i + 6], abs(x[i + 6])) for i in range(0, 7 * k, 7)):
            ab = b - a
            s = np.clip((sub - a) @ ab / max(ab @ ab, 1e-12), 0, 1)
            dist = np.linalg.norm(sub - a - s[:, None] * ab, axis=1)
            gap = np.minimum(gap, np.maximum(dist - r, 0))
            surf = a + t[:, None] * ab + r * unit
            inside = [np.maximum((surf @ p[:, :3].T + p[:, 3]).max(1), 0) for p in planes]
            out = max(out, np.min(inside, 0).max())
        return max(gap.max(), out)

    best = np.inf
    for trial in range(4):
        side, across = 1 + trial % 2, 2 - trial % 2
        r0 = np.percentile(np.abs(proj[:, across]), 60) * (0.8 if trial > 1 else 1.0)
        x0 = []
        for i in range(k):
            off = centre + axes[side] * (i - (k - 1) / 2) * np.ptp(proj[:, side]) / (k + 1)
            x0 += [*(off + axes[0] * (proj[:, 0].min() + r0)),
                   *(off + axes[0] * (proj[:, 0].max() - r0)), r0]  # fmt: skip
        res = minimize(cost, np.array(x0), method="Nelder-Mead",
                       options={"maxiter": 20000, "xatol": 1e-5, "fatol": 1e-6, "adaptive": True})
        best = min(best, float(res.fun))
    return {"body": body, "capsules": k, "cost_fit": best}
