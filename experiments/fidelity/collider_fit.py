"""How far sirl_jax's primitive colliders are from HumanoidBench's, link by link.

Both robots are posed at the same qpos (HumanoidBench's h1hand qpos0, which our body frames
reproduce) and compared per body, in world coordinates, as the unions of each side's collision
geoms (HumanoidBench: convex meshes, as MuJoCo collides them, i.e. their convex hulls, plus its
primitives; sirl_jax: primitives). Two one-sided distances per link:

- `hb_out`: the largest distance by which a point of HumanoidBench's collider surface lies
  outside ours (the part of its collider we do not cover);
- `ours_out`: the largest distance by which a point of our collider surface lies outside
  HumanoidBench's (what we add);
- `hb_out_robot`: as `hb_out`, against the union of all our colliders (a link we give no
  collider of its own may be covered by its neighbours'). For a link without a collider of
  ours, `hb_out` is the extent of HumanoidBench's.

Distances to primitives are analytic; the distance of an outside point to a convex hull is
the distance to the nearest of ~20,000 area-uniform samples of its surface (an upper bound,
within about 1 mm for these link sizes). HumanoidBench's robot is read from a checkout:

    .venv/bin/python -m experiments.fidelity.collider_fit \
        --hb-robot CHECKOUT/humanoid_bench/assets/robots/h1hand_pos.xml
        [--tolerance 0.01] [--out docs/results/collider_fit.json]
        [--refit] [--capsules K --links left_hip_pitch_link,left_knee_link]
        [--hull 16,32,48 --links torso_link,pelvis [--out FILE.jsonl]]

`--capsules K` asks how close K capsules per link could come: for each link of `--links`, the
minimax fit of K capsules at once (max of HumanoidBench outside their union and their
surfaces outside HumanoidBench's hull), Nelder-Mead from four starts (the capsules side by
side along the link's second or third principal axis), the best printed.

`--hull K1,K2` fits convex mesh colliders instead: for each link of `--links`, a K-vertex
inner approximation of HumanoidBench's hull (`greedy_hull`), with how far HumanoidBench's
surface lies outside it (its own surface never lies outside HumanoidBench's).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from sirl_jax.envs import h1

G = mujoco.mjtGeom


def _colliders(m: mujoco.MjModel, names=None) -> dict[str, list[int]]:
    """Collision geom ids by body name: the geoms named in `names` (ours: every robot group,
    whether or not a task switches it on), else those with a contype or conaffinity bit."""
    out: dict[str, list[int]] = {}
    for g in range(m.ngeom):
        on = (
            m.geom(g).name in names
            if names is not None
            else m.geom_contype[g] or m.geom_conaffinity[g]
        )
        if on and m.geom_bodyid[g] != 0:
            out.setdefault(m.body(m.geom_bodyid[g]).name, []).append(g)
    return out


def _ours(model: mujoco.MjModel) -> dict[str, list[int]]:
    groups = h1.Robot(model).geom_groups
    return _colliders(model, {n for names in groups.values() for n in names})


def _local_sdf(gtype: int, size: np.ndarray, p: np.ndarray) -> np.ndarray:
    """[N] signed distance of local points p [N, 3] to a primitive."""
    if gtype == G.mjGEOM_SPHERE:
        return np.linalg.norm(p, axis=1) - size[0]
    if gtype == G.mjGEOM_CAPSULE:
        z = np.clip(p[:, 2], -size[1], size[1])
        return np.linalg.norm(p - np.stack([0 * z, 0 * z, z], 1), axis=1) - size[0]
    if gtype == G.mjGEOM_CYLINDER:
        d = np.stack([np.linalg.norm(p[:, :2], axis=1) - size[0], np.abs(p[:, 2]) - size[1]], 1)
        return np.linalg.norm(np.maximum(d, 0), axis=1) + np.minimum(d.max(1), 0)
    if gtype == G.mjGEOM_BOX:
        q = np.abs(p) - size
        return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(1), 0)
    raise ValueError(f"no analytic distance for geom type {gtype}")


def _primitive_surface(gtype: int, size: np.ndarray, n: int, rng) -> np.ndarray:
    """[~n, 3] local points on a primitive's surface (projected samples of its bounding box)."""
    if gtype == G.mjGEOM_SPHERE:
        v = rng.normal(size=(n, 3))
        return size[0] * v / np.linalg.norm(v, axis=1, keepdims=True)
    if gtype == G.mjGEOM_CAPSULE:  # side and caps, area-weighted
        r, h = size[0], size[1]
        side = rng.uniform(size=n) < (2 * h) / (2 * h + 2 * r)
        v = rng.normal(size=(n, 3))
        v = r * v / np.linalg.norm(v, axis=1, keepdims=True)
        ang = rng.uniform(0, 2 * np.pi, n)
        v[side] = np.stack(
            [r * np.cos(ang[side]), r * np.sin(ang[side]), rng.uniform(-h, h, side.sum())], 1
        )
        v[~side, 2] += np.sign(v[~side, 2]) * h
        return v
    if gtype in (G.mjGEOM_BOX, G.mjGEOM_CYLINDER):
        half = size if gtype == G.mjGEOM_BOX else np.array([size[0], size[0], size[1]])
        p = rng.uniform(-1, 1, (n, 3)) * half
        if gtype == G.mjGEOM_BOX:
            axis = rng.integers(0, 3, n)
            p[np.arange(n), axis] = np.sign(rng.uniform(-1, 1, n)) * half[axis]
            return p
        side = rng.uniform(size=n) < 0.5
        ang = rng.uniform(0, 2 * np.pi, n)
        p[side, 0], p[side, 1] = size[0] * np.cos(ang[side]), size[0] * np.sin(ang[side])
        p[~side, 2] = np.sign(rng.uniform(-1, 1, (~side).sum())) * size[1]
        return p[(np.linalg.norm(p[:, :2], axis=1) <= size[0] + 1e-9)]
    raise ValueError(f"no surface sampler for geom type {gtype}")


class _Geom:
    """One collision geom in world coordinates: signed distance and surface samples."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, g: int, rng, n: int = 20000):
        self.type, self.size = int(m.geom_type[g]), m.geom_size[g].copy()
        self.pos, self.mat = d.geom_xpos[g].copy(), d.geom_xmat[g].reshape(3, 3).copy()
        if self.type == G.mjGEOM_MESH:
            k = m.geom_dataid[g]
            a, b = m.mesh_vertadr[k], m.mesh_vertadr[k] + m.mesh_vertnum[k]
            hull = ConvexHull(m.mesh_vert[a:b].astype(np.float64))
            self.planes = hull.equations  # [F, 4]: n.x + c <= 0 inside
            tri = hull.points[hull.simplices]  # [F, 3, 3]
            area = 0.5 * np.linalg.norm(
                np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1
            )
            pick = rng.choice(len(tri), n, p=area / area.sum())
            u, v = rng.uniform(size=(2, n))
            flip = u + v > 1
            u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
            t = tri[pick]
            local = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
            self.local_surface = np.concatenate([local, hull.points[hull.vertices]])
        else:
            self.local_surface = _primitive_surface(self.type, self.size, n, rng)
            self.planes = None  # a primitive's hull is made from its samples when a fit needs it
        self._tree = cKDTree(self.local_surface)

    def surface(self) -> np.ndarray:
        return self.local_surface @ self.mat.T + self.pos

    def outside(self, x: np.ndarray) -> np.ndarray:
        """[N] distance of world points outside this geom (0 inside)."""
        p = (x - self.pos) @ self.mat
        if self.type == G.mjGEOM_MESH:
            s = p @ self.planes[:, :3].T + self.planes[:, 3]
            out = s.max(1) > 0
            dist = np.zeros(len(p))
            if out.any():
                dist[out] = self._tree.query(p[out])[0]
            return dist
        return np.maximum(_local_sdf(self.type, self.size, p), 0.0)


def _posed(model: mujoco.MjModel, qpos: np.ndarray) -> mujoco.MjData:
    d = mujoco.MjData(model)
    d.qpos[: len(qpos)] = qpos
    mujoco.mj_kinematics(model, d)
    return d


def _describe(m: mujoco.MjModel, g: int) -> str:
    return mujoco.mjtGeom(int(m.geom_type[g])).name[7:].lower()


def compare(hb: mujoco.MjModel, ours: mujoco.MjModel, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    qpos = hb.qpos0[: ours.nq].copy()
    d_hb, d_us = _posed(hb, qpos), _posed(ours, qpos)
    col_hb, col_us = _colliders(hb), _ours(ours)
    every = [_Geom(ours, d_us, g, rng, n=200) for ids in col_us.values() for g in ids]
    rows = []
    for body in sorted(set(col_hb) | set(col_us)):
        g_hb = [_Geom(hb, d_hb, g, rng) for g in col_hb.get(body, [])]
        g_us = [_Geom(ours, d_us, g, rng) for g in col_us.get(body, [])]
        row = {
            "body": body,
            "hb": "+".join(sorted(_describe(hb, g) for g in col_hb.get(body, []))) or "-",
            "ours": "+".join(sorted(_describe(ours, g) for g in col_us.get(body, []))) or "-",
            "hb_out": None,
            "ours_out": None,
            "hb_out_robot": None,
        }
        if g_hb and g_us:
            pts_hb = np.concatenate([g.surface() for g in g_hb])
            pts_us = np.concatenate([g.surface() for g in g_us])
            row["hb_out"] = float(np.min([g.outside(pts_hb) for g in g_us], axis=0).max())
            row["ours_out"] = float(np.min([g.outside(pts_us) for g in g_hb], axis=0).max())
        elif g_hb:  # a HumanoidBench collider we leave out: its extent
            pts_hb = np.concatenate([g.surface() for g in g_hb])
            row["hb_out"] = float(np.ptp(pts_hb, axis=0).max())
        if g_hb:  # outside every collider of ours, whichever link holds it
            row["hb_out_robot"] = float(np.min([g.outside(pts_hb) for g in every], axis=0).max())
        rows.append(row)
    return rows


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hb-robot", type=Path, required=True, help="HumanoidBench's h1hand_pos.xml")
    p.add_argument("--tolerance", type=float, default=0.01, help="flag links off by more (m)")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument(
        "--variant", choices=("h1hand", "h1"), default="h1hand", help="our robot to compare"
    )
    p.add_argument("--refit", action="store_true", help="print refitted capsules, one per line")
    p.add_argument("--capsules", type=int, default=0, help="fit K capsules per --links link")
    p.add_argument("--hull", default="", help="comma-separated k: fit k-vertex inner hulls "
                   "to each --links link (greedy_hull) and print how far each is off")
    p.add_argument("--links", default="left_hip_pitch_link,left_knee_link,pelvis,torso_link")
    args = p.parse_args(argv)
    if not args.hb_robot.is_file():
        raise SystemExit(f"error: --hb-robot {str(args.hb_robot)!r} is not a file")
    hb = mujoco.MjModel.from_xml_path(str(args.hb_robot))
    if args.hull:
        for body in args.links.split(","):
            for row in hull_fit(hb, h1.load_model(args.variant), body,
                                [int(k) for k in args.hull.split(",")]):  # fmt: skip
                print(f"{body}: {row['vertices']} vertices, {row['triangles']} triangles, "
                      f"HB out {100 * row['hb_out']:.2f} cm, ours out 0")
                if args.out:
                    args.out.parent.mkdir(parents=True, exist_ok=True)
                    with args.out.open("a") as f:
                        f.write(json.dumps(row) + "\n")
        return
    if args.capsules:
        for body in args.links.split(","):
            print(json.dumps(multi_fit(hb, h1.load_model(args.variant), body, args.capsules)))
        return
    if args.refit:
        for row in refit(hb, h1.load_model(args.variant)):
            print(json.dumps(row))
        return
    rows = compare(hb, h1.load_model(args.variant))
    print("| link | HumanoidBench | sirl_jax | HB outside ours (cm) | ours outside HB (cm) "
          "| HB outside all of ours (cm) | |")  # fmt: skip
    print("|---|---|---|---:|---:|---:|---|")
    for r in rows:
        keys = ("hb_out", "ours_out", "hb_out_robot")
        cm = ["-" if r[k] is None else f"{100 * r[k]:.1f}" for k in keys]
        worst = max(v for v in (r["hb_out"], r["ours_out"], 0.0) if v is not None)
        flag = "off" if worst > args.tolerance else ""
        print(f"| {r['body']} | {r['hb']} | {r['ours']} | {' | '.join(cm)} | {flag} |")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(rows, indent=1) + "\n")


def _hull_points(geoms: list[_Geom]) -> tuple[np.ndarray, list[np.ndarray]]:
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
    d_hb, d_us = _posed(hb, qpos), _posed(ours, qpos)
    col_hb, col_us = _colliders(hb), _ours(ours)
    out = []
    for body, ids in sorted(col_us.items()):
        if body not in col_hb or body.startswith(("lh_", "rh_")):
            continue
        hb_geoms = [_Geom(hb, d_hb, g, rng) for g in col_hb[body]]
        verts, planes = _hull_points(hb_geoms)
        for g in ids:
            if ours.geom_type[g] != G.mjGEOM_CAPSULE:
                continue
            rest = [_Geom(ours, d_us, k, rng) for k in ids if k != g]
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
    d_hb, d_us = _posed(hb, qpos), _posed(ours, qpos)
    if body not in (col := _colliders(hb)):
        raise SystemExit(f"error: HumanoidBench has no collider on {body!r}")
    b = ours.body(body).id
    pos, mat = d_us.xpos[b], d_us.xmat[b].reshape(3, 3)
    hb_geoms = [_Geom(hb, d_hb, g, rng) for g in col[body]]
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
    d_hb = _posed(hb, hb.qpos0[: ours.nq].copy())
    if body not in (col := _colliders(hb)):
        raise SystemExit(f"error: HumanoidBench has no collider on {body!r}")
    verts, planes = _hull_points([_Geom(hb, d_hb, g, rng) for g in col[body]])
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


if __name__ == "__main__":
    main()
