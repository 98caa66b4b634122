"""Minimal reproduction: MJX's capsule-box collision misses contacts near the box's edges.

One static box (a maze block, half 0.75 x 0.75 x 0.6) and one free capsule (r 0.06, half-length
0.15, about a thigh). MuJoCo C (`mj_forward`) and MJX-JAX (`mjx.forward`, the same model, no
`max_geom_pairs`, so the pair is never pruned) are asked for the contact of the same poses:

1. the pose below, where a capsule end sits 1.3 cm from a vertical edge of the box, outside
   both faces' planes: C finds a contact 4.7 cm deep, MJX reports none (dist +1, its "no
   contact" value);
2. a sweep of random poses around the box's surface: how many C contacts MJX misses, and how
   deep they are.

    .venv/bin/python -m experiments.fidelity.mjx_capsule_box_miss [--poses 4000] [--seed 0]

The misses come from `collision_convex._capsule_convex`. It picks the face of least
penetration and clips the capsule's segment to that face; here the segment lies wholly outside
the face's side planes, so the face contact is empty. The edge contact (capsule end to box edge,
4.7 cm deep) is then discarded because its axis is within 0.99 of that face's normal ("prefer
the face contact"): |axis . normal| = 0.996 for the pose below. Neither contact survives. sirl_jax's
contact rules therefore read `sirl_jax.envs.overlap` (an exact overlap test) instead of MJX's
contact slots; the physics keeps MJX's collision.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

XML = """<mujoco><worldbody>
  <geom name="block" type="box" size="0.75 0.75 0.6" pos="0 0 0.6"/>
  <body name="capsule"><freejoint/><geom name="capsule" type="capsule" size="0.06 0.15"/></body>
</worldbody></mujoco>"""
EDGE_POSE = np.array([0.866, -0.828, 0.844, 0.351, -0.86, -0.133, 0.345])
"""Free-joint qpos (position, quaternion) of the capsule in the missed edge contact."""


def contacts(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """([N] deepest C contact dist (+inf: none), [N] deepest MJX slot dist) of capsule poses."""
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    c = np.full(len(poses), np.inf)
    for i, q in enumerate(poses):
        d.qpos[:] = q / np.r_[1, 1, 1, np.full(4, np.linalg.norm(q[3:]))]
        mujoco.mj_forward(m, d)
        if d.ncon:
            c[i] = min(d.contact[k].dist for k in range(d.ncon))
    mx = mjx.put_model(m)

    @jax.jit
    def deepest(qpos):
        def one(q):
            out = mjx.forward(mx, mjx.make_data(mx).replace(qpos=q))
            return out._impl.contact.dist.min()

        return jax.vmap(one)(qpos)

    q = jnp.asarray(poses, jnp.float32)
    q = q.at[:, 3:].set(q[:, 3:] / jnp.linalg.norm(q[:, 3:], axis=1, keepdims=True))
    return c, np.asarray(deepest(q))


def random_poses(n: int, seed: int) -> np.ndarray:
    """[n, 7] capsule poses around the box surface (faces, edges and corners alike)."""
    rng = np.random.default_rng(seed)
    half = np.array([0.75, 0.75, 0.6])
    p = rng.uniform(-1, 1, (n, 3)) * half
    axis = rng.integers(0, 3, n)
    p[np.arange(n), axis] = np.sign(rng.uniform(-1, 1, n)) * half[axis]
    p += np.array([0, 0, 0.6]) + rng.normal(size=(n, 3)) * 0.1
    quat = rng.normal(size=(n, 4))
    return np.concatenate([p, quat / np.linalg.norm(quat, axis=1, keepdims=True)], 1)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--poses", type=int, default=4000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    c, x = contacts(EDGE_POSE[None])
    print(f"edge pose: C dist {c[0]:+.4f} m, MJX dist {x[0]:+.4f} m (MJX +1 = no contact)")
    c, x = contacts(random_poses(args.poses, args.seed))
    hit = c < 0
    miss = hit & (x >= 0)
    share = 100 * miss.sum() / max(hit.sum(), 1)
    extra = ((x < 0) & ~hit).sum()
    print(f"random poses: {args.poses}, C contacts {hit.sum()}, MJX misses {miss.sum()} "
          f"({share:.2f}%), MJX extra {extra}")  # fmt: skip
    if miss.any():
        print(f"missed depths (m): max {-c[miss].min():.4f}, median {-np.median(c[miss]):.4f}")


if __name__ == "__main__":
    main()
