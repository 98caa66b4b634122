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

from experiments.fidelity.collider_geoms import Geom, colliders, our_colliders, posed
from experiments.fidelity.collider_refit import hull_fit, multi_fit, refit
from sirl_jax.envs import h1


def _describe(m: mujoco.MjModel, g: int) -> str:
    return mujoco.mjtGeom(int(m.geom_type[g])).name[7:].lower()


def compare(hb: mujoco.MjModel, ours: mujoco.MjModel, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    qpos = hb.qpos0[: ours.nq].copy()
    d_hb, d_us = posed(hb, qpos), posed(ours, qpos)
    col_hb, col_us = colliders(hb), our_colliders(ours)
    every = [Geom(ours, d_us, g, rng, n=200) for ids in col_us.values() for g in ids]
    rows = []
    for body in sorted(set(col_hb) | set(col_us)):
        g_hb = [Geom(hb, d_hb, g, rng) for g in col_hb.get(body, [])]
        g_us = [Geom(ours, d_us, g, rng) for g in col_us.get(body, [])]
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


if __name__ == "__main__":
    main()
