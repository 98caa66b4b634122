"""Exact overlap tests between primitive geoms, for the contact rules of rewards and terminations.

HumanoidBench's obstacle penalties and balance's termination scan every contact MuJoCo found.
MJX's contact slots are a pruned subset (`max_geom_pairs` keeps the k candidate pairs with the
closest bounding spheres per collision function), and its capsule-box narrow phase misses some
edge contacts (docs/tasks.md, "MJX's capsule-box miss"). A rule that must see every
touching pair asks `PairQuery` instead: once per control step, on the kinematics `mjx.step`
returned, whether any pair of a static list of geom pairs overlaps.

Supported types: sphere, capsule and box against each other (the robot's colliders and the
task obstacles), plus any of them against the z = 0 floor plane (`below_floor`). Pairs are
ordered sphere < capsule < box and tested in one vmapped group per type pair:

- sphere-sphere, sphere-capsule: closed form;
- sphere-box: the box's signed distance at the centre;
- capsule-capsule, capsule-box: the minimum over the segment of a convex distance (golden-section
  search, 32 iterations: 2e-7 of the segment length);
- box-box: the separating-axis test (15 axes).

With more than `max_candidates` pairs, a cheap lower bound of each pair's distance (the
obstacle's distance to the other geom's centre minus that geom's bounding radius) ranks them
and only the nearest `max_candidates` are tested exactly; `PairQuery.candidates` counts how
many pairs the bound could not exclude, so a caller can check that the cap was never binding.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

SPHERE, CAPSULE, BOX = (int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE),
                        int(mujoco.mjtGeom.mjGEOM_BOX))  # fmt: skip
SUPPORTED = (SPHERE, CAPSULE, BOX)
_GOLDEN = 0.6180339887498949
_ITERS = 32


def box_sdf(p: jax.Array, pos: jax.Array, mat: jax.Array, half: jax.Array) -> jax.Array:
    """[] signed distance of world point p [3] to a box (centre, [3, 3] rotation, half sizes)."""
    q = jnp.abs(mat.T @ (p - pos)) - half
    return jnp.linalg.norm(jnp.maximum(q, 0.0)) + jnp.minimum(q.max(), 0.0)


def segment_dist(p: jax.Array, a: jax.Array, b: jax.Array) -> jax.Array:
    """[] distance of point p to the segment a-b."""
    ab = b - a
    t = jnp.clip(jnp.dot(p - a, ab) / jnp.maximum(jnp.dot(ab, ab), 1e-12), 0.0, 1.0)
    return jnp.linalg.norm(p - (a + t * ab))


def min_on_segment(f, a: jax.Array, b: jax.Array) -> jax.Array:
    """[] min over t in [0, 1] of f(a + t (b - a)) for a convex f (golden-section search)."""

    def body(_, lo_hi):
        lo, hi = lo_hi
        t1, t2 = hi - _GOLDEN * (hi - lo), lo + _GOLDEN * (hi - lo)
        left = f(a + t1 * (b - a)) < f(a + t2 * (b - a))
        return jnp.where(left, lo, t1), jnp.where(left, t2, hi)

    lo, hi = jax.lax.fori_loop(0, _ITERS, body, (jnp.zeros(()), jnp.ones(())))
    ends = jnp.minimum(f(a), f(b))
    return jnp.minimum(f(a + 0.5 * (lo + hi) * (b - a)), ends)


def _segment(pos, mat, size):
    half = mat[:, 2] * size[1]
    return pos - half, pos + half


def _box_box(pos1, mat1, half1, pos2, mat2, half2) -> jax.Array:
    """[] bool, the boxes overlap (no separating axis among the 15 of the SAT)."""
    cross = jnp.cross(mat1.T[:, None, :], mat2.T[None, :, :]).reshape(9, 3)
    axes = jnp.concatenate([mat1.T, mat2.T, cross])  # [15, 3]
    norm = jnp.linalg.norm(axes, axis=1)
    valid = norm > 1e-6  # parallel edges give no axis
    axes = axes / jnp.where(valid, norm, 1.0)[:, None]
    r1 = jnp.abs(axes @ mat1) @ half1
    r2 = jnp.abs(axes @ mat2) @ half2
    gap = jnp.abs(axes @ (pos2 - pos1)) - r1 - r2
    return ~jnp.any(valid & (gap > 0.0))


def overlap(t1: int, g1, t2: int, g2) -> jax.Array:
    """[] bool, two geoms (pos [3], mat [3, 3], size [3]) of types t1 <= t2 overlap."""
    (p1, m1, s1), (p2, m2, s2) = g1, g2
    if (t1, t2) == (SPHERE, SPHERE):
        return jnp.linalg.norm(p1 - p2) < s1[0] + s2[0]
    if (t1, t2) == (SPHERE, CAPSULE):
        return segment_dist(p1, *_segment(p2, m2, s2)) < s1[0] + s2[0]
    if (t1, t2) == (SPHERE, BOX):
        return box_sdf(p1, p2, m2, s2) < s1[0]
    if (t1, t2) == (CAPSULE, CAPSULE):
        a2, b2 = _segment(p2, m2, s2)
        d = min_on_segment(lambda p: segment_dist(p, a2, b2), *_segment(p1, m1, s1))
        return d < s1[0] + s2[0]
    if (t1, t2) == (CAPSULE, BOX):
        d = min_on_segment(lambda p: box_sdf(p, p2, m2, s2), *_segment(p1, m1, s1))
        return d < s1[0]
    if (t1, t2) == (BOX, BOX):
        return _box_box(p1, m1, s1, p2, m2, s2)
    raise ValueError(f"no overlap test for geom types {t1}, {t2}; supported: {SUPPORTED}")


def _centre_bound(t_obstacle: int, obstacle, centre: jax.Array) -> jax.Array:
    """[] distance from a point to an obstacle geom's surface (negative inside)."""
    pos, mat, size = obstacle
    if t_obstacle == SPHERE:
        return jnp.linalg.norm(centre - pos) - size[0]
    if t_obstacle == CAPSULE:
        return segment_dist(centre, *_segment(pos, mat, size)) - size[0]
    return box_sdf(centre, pos, mat, size)


def lowest_point(gtype: int, pos: jax.Array, mat: jax.Array, size: jax.Array) -> jax.Array:
    """[] the smallest world z of a sphere, capsule or box."""
    if gtype == SPHERE:
        return pos[2] - size[0]
    if gtype == CAPSULE:
        return pos[2] - jnp.abs(mat[2, 2]) * size[1] - size[0]
    if gtype == BOX:
        return pos[2] - jnp.abs(mat[2]) @ size
    raise ValueError(f"no lowest point for geom type {gtype}; supported: {SUPPORTED}")


class PairQuery:
    """Which of the pairs (a, b), a in `geoms_a`, b in `geoms_b`, overlap, from `mjx.Data`
    kinematics (`geom_xpos`, `geom_xmat`). `geoms_b` are the obstacles: the candidate bound
    ranks pairs by b's distance to a's centre."""

    def __init__(self, model: mujoco.MjModel, geoms_a, geoms_b, max_candidates: int = 32):
        if max_candidates < 1:
            raise ValueError(f"max_candidates must be >= 1, got {max_candidates}")
        for g in [*geoms_a, *geoms_b]:
            if int(model.geom_type[g]) not in SUPPORTED:
                name = model.geom(g).name
                raise ValueError(f"geom {name!r} has type {int(model.geom_type[g])}; "
                                 f"supported: sphere, capsule, box")  # fmt: skip
        self._size = jnp.asarray(model.geom_size, jnp.float32)
        self._rbound = jnp.asarray(model.geom_rbound, jnp.float32)
        self._groups = {}
        for a in geoms_a:
            for b in geoms_b:
                ta, tb = int(model.geom_type[a]), int(model.geom_type[b])
                self._groups.setdefault((ta, tb), []).append((a, b))
        self._groups = {k: np.asarray(v, np.int32) for k, v in self._groups.items()}
        self.num_pairs = sum(len(v) for v in self._groups.values())
        self.max_candidates = max_candidates

    def _geom(self, d, ids):
        return d.geom_xpos[ids], d.geom_xmat[ids].reshape(-1, 3, 3), self._size[ids]

    def _group(self, d, ta: int, tb: int, pairs: np.ndarray) -> tuple[jax.Array, jax.Array]:
        """([k] overlap of the tested pairs, [] count of pairs the bound could not exclude)."""
        ga, gb = self._geom(d, pairs[:, 0]), self._geom(d, pairs[:, 1])
        bound = jax.vmap(lambda ob, c: _centre_bound(tb, ob, c))(gb, ga[0])
        bound = bound - self._rbound[pairs[:, 0]]
        candidates = jnp.sum(bound < 0.0)
        if len(pairs) > self.max_candidates:
            _, idx = jax.lax.top_k(-bound, self.max_candidates)
            ga, gb = jax.tree.map(lambda x: x[idx], ga), jax.tree.map(lambda x: x[idx], gb)
            bound = bound[idx]
        if ta <= tb:
            hit = jax.vmap(lambda g1, g2: overlap(ta, g1, tb, g2))(ga, gb)
        else:
            hit = jax.vmap(lambda g1, g2: overlap(tb, g2, ta, g1))(ga, gb)
        return hit & (bound < 0.0), candidates

    def any(self, d) -> jax.Array:
        """[] bool, some pair overlaps."""
        hits = [self._group(d, ta, tb, p)[0].any() for (ta, tb), p in self._groups.items()]
        return jnp.any(jnp.stack(hits)) if hits else jnp.zeros((), bool)

    def candidates(self, d) -> jax.Array:
        """[] int, pairs whose distance bound is negative (tested only up to `max_candidates`
        per type pair)."""
        counts = [self._group(d, ta, tb, p)[1] for (ta, tb), p in self._groups.items()]
        return jnp.max(jnp.stack(counts)) if counts else jnp.zeros((), jnp.int32)


def below_floor(model: mujoco.MjModel, geoms, d) -> jax.Array:
    """[] bool, some geom of `geoms` reaches below the z = 0 floor plane."""
    geoms = np.asarray(geoms, np.int32)
    size = jnp.asarray(model.geom_size, jnp.float32)
    low = []
    for t in SUPPORTED:
        ids = geoms[model.geom_type[geoms] == t]
        if len(ids):
            low.append(
                jax.vmap(lambda p, m, s, t=t: lowest_point(t, p, m, s))(
                    d.geom_xpos[ids], d.geom_xmat[ids].reshape(-1, 3, 3), size[ids]
                ).min()
            )
    return jnp.min(jnp.stack(low)) < 0.0 if low else jnp.zeros((), bool)
