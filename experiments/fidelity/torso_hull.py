"""The torso as one convex hull of our own, measured against the installed primitives.

`collider_fit --hull` fits k-vertex hulls inside HumanoidBench's link meshes; this asks what the
torso's hull would cost and buy. Inside a `with torso_hull(vertices):` block every robot spec
built (`h1.robot_spec`) carries the hull as its "torso" collider, and the box's two partners,
the head sphere and the shoulder-housing capsule, shrink to 1 mm spheres inside it (they keep
their names, so every contact group still resolves). Two measurements:

    # rate with the hull / rate with the primitives, side by side, E = 64:
    .venv/bin/python -m experiments.fidelity.torso_hull \
        --hb-robot CHECKOUT/humanoid_bench/assets/robots/h1hand_pos.xml \
        --k 32 --speed bare,sit_simple,push,kitchen
    # hb_parity with the hull (its own arguments after --):
    .venv/bin/python -m experiments.fidelity.torso_hull --hb-robot ... --k 32 -- \
        --python REFENV/bin/python --hb-checkout CHECKOUT --states 500 \
        --tasks push,sit_simple --out FILE

Results: docs/robot.md ("Convex hulls of our own").
"""

from __future__ import annotations

import argparse
import contextlib
import statistics

import mujoco
import numpy as np

from experiments.fidelity import collider_fit
from sirl_jax.envs import h1


@contextlib.contextmanager
def torso_hull(vertices: np.ndarray):
    """Every `h1.robot_spec` of a hand variant built inside carries the hull as "torso"."""
    original = h1.robot_spec

    def patched(variant: str = "h1hand", contacts: str = "locomotion") -> mujoco.MjSpec:
        spec = original(variant, contacts)
        if variant not in h1.HAND_VARIANTS:
            return spec
        spec.add_mesh(name="torso_hull", uservert=vertices.astype(np.float32).ravel().tolist())
        torso = spec.geom("torso")
        torso.type, torso.meshname, torso.pos = mujoco.mjtGeom.mjGEOM_MESH, "torso_hull", (0, 0, 0)
        head, housing = spec.geom("head"), spec.geom("shoulders")
        head.size, head.pos = (1e-3, 0, 0), (0, 0, 0.3)
        housing.size, housing.fromto = (1e-3, 0, 0), (0, 0, 0.3, 0, 0, 0.31)
        return spec

    h1.robot_spec = patched
    try:
        yield
    finally:
        h1.robot_spec = original


def speed(vertices: np.ndarray, names: list[str], rounds: int = 5) -> None:
    from experiments.bench import bench_tasks as bt
    from sirl_jax.envs import tasks
    from sirl_jax.envs.humanoid import HumanoidEnv

    rows = {r.name: r for r in (*tasks.LOCOMOTION, *tasks.MANIPULATION)}

    def env(name: str):
        if name == "bare":
            return HumanoidEnv(bt.BareTask(), "h1hand")
        row = rows[name]
        variant = row.robot if row in tasks.MANIPULATION else "h1hand"
        return HumanoidEnv(row.task(), variant, success_bar=row.success_bar)

    for name in names:
        prim = bt.Stepper(env(name), 64, 10)
        with torso_hull(vertices):
            hull = bt.Stepper(env(name), 64, 10)
        a, b = [], []
        for _ in range(rounds):
            a.append(prim.rate())
            b.append(hull.rate())
        slots = [len(bt.mjx_contact_dims(s.env.mj_model)) for s in (prim, hull)]
        print(f"{name}: primitives {statistics.median(a):.0f} steps/s, hull "
              f"{statistics.median(b):.0f} steps/s, ratio "
              f"{statistics.median(b) / statistics.median(a):.3f}, slots {slots[0]} -> {slots[1]}",
              flush=True)  # fmt: skip
        del prim, hull


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hb-robot", required=True, help="HumanoidBench's h1hand_pos.xml")
    p.add_argument("--k", type=int, default=32, help="hull vertices")
    p.add_argument("--speed", default="", help="comma-separated tasks (and 'bare') to time")
    p.add_argument("parity", nargs=argparse.REMAINDER, help="-- then hb_parity's arguments")
    args = p.parse_args()
    if args.k < 4:
        raise SystemExit(f"error: --k {args.k}: a hull needs at least 4 vertices")
    hb = mujoco.MjModel.from_xml_path(args.hb_robot)
    (row,) = collider_fit.hull_fit(hb, h1.load_model("h1hand"), "torso_link", [args.k])
    vertices = np.asarray(row["local_vertices"])
    print(f"torso hull: {row['vertices']} vertices, HB out {100 * row['hb_out']:.2f} cm")
    if args.speed:
        speed(vertices, [n for n in args.speed.split(",") if n])
    parity = [a for a in args.parity if a != "--"]
    if parity:
        from experiments.fidelity import hb_parity

        with torso_hull(vertices):
            hb_parity.main(parity)


if __name__ == "__main__":
    main()
