"""The colliders collider_fit compares, as point sets and distance functions: each link's
collision geoms on either robot, our primitives' signed distances and area-uniform surface
samples, HumanoidBench's meshes as their convex hulls (`Geom`), and a model posed at a qpos."""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from sirl_jax.envs import h1

G = mujoco.mjtGeom


def colliders(m: mujoco.MjModel, names=None) -> dict[str, list[int]]:
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


def our_colliders(model: mujoco.MjModel) -> dict[str, list[int]]:
    groups = h1.Robot(model).geom_groups
    return colliders(model, {n for names in groups.values() for n in names})


def local_sdf(gtype: int, size: np.ndarray, p: np.ndarray) -> np.ndarray:
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


def primitive_surface(gtype: int, size: np.ndarray, n: int, rng) -> np.ndarray:
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


class Geom:
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
            self.local_surface = primitive_surface(self.type, self.size, n, rng)
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
        return np.maximum(local_sdf(self.type, self.size, p), 0.0)


def posed(model: mujoco.MjModel, qpos: np.ndarray) -> mujoco.MjData:
    d = mujoco.MjData(model)
    d.qpos[: len(qpos)] = qpos
    mujoco.mj_kinematics(model, d)
    return d
