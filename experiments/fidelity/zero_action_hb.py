"""The zero action (every actuator at the middle of its ctrlrange) on HumanoidBench's own model.

    .venv/bin/python -m experiments.fidelity.zero_action_hb \
        --hb-env CHECKOUT/humanoid_bench/assets/envs/h1hand_pos_sit_simple.xml

Loads HumanoidBench's scene XML (a checkout of carlosferrazza/humanoid-bench; nothing of it is
copied here) in MuJoCo C, resets to its keyframe 0, holds ctrl = (low + high) / 2 and steps
1,000 control steps of 10 substeps. It prints the pelvis position every 200 steps and the first
step at which the pelvis falls under 0.5 m (sit_simple's termination), if any, and the return
under sit_simple's reward as the spec writes HumanoidBench's (humanoidbench.md, section 3:
small_control * sit * dont_move, evaluated after each control step): whether standing still
earns on HumanoidBench's own sit_simple what it earns on ours (docs/results/sit_simple_study.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mujoco
import numpy as np


def tol(x, lo: float, hi: float, margin: float, sigmoid: str = "gaussian", vam: float = 0.1):
    """dm_control's `rewards.tolerance` for the three sigmoids the spec uses."""
    d = max(lo - x, x - hi, 0.0) / margin
    if d == 0.0:
        return 1.0
    if sigmoid == "linear":
        return max(0.0, 1.0 - d * (1.0 - vam))
    if sigmoid == "quadratic":
        return max(0.0, 1.0 - d * d * (1.0 - vam))
    return float(np.exp(-0.5 * (d * np.sqrt(-2.0 * np.log(vam))) ** 2))


def sit_simple_reward(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """HumanoidBench's sit_simple per-step reward, written from the spec's formula."""
    chair = d.body("chair").xpos
    sitting = tol(d.qpos[2], 0.68, 0.72, 0.2)
    on_chair = tol(d.qpos[0] - chair[0], -0.19, 0.19, 0.2) * tol(d.qpos[1] - chair[1], 0, 0, 0.1)
    posture = tol(d.site("head").xpos[2] - d.site("imu").xpos[2], 0.35, 0.45, 0.3)
    upright = tol(d.body("torso_link").xmat[8], 0.95, np.inf, 0.9, "linear", 0.0)
    sit = (0.5 * sitting + 0.5 * on_chair) * upright * posture
    small_control = (4.0 + np.mean(np.maximum(0.0, 1.0 - (d.actuator_force / 10.0) ** 2))) / 5.0
    v = d.sensor("pelvis_subtreelinvel").data
    dont_move = (tol(v[0], 0, 0, 2.0) + tol(v[1], 0, 0, 2.0)) / 2.0
    return float(small_control * sit * dont_move)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hb-env", type=Path, required=True, help="HumanoidBench's env XML")
    ap.add_argument("--steps", type=int, default=1000)
    args = ap.parse_args(argv)
    if not args.hb_env.is_file():
        raise SystemExit(f"error: --hb-env {str(args.hb_env)!r} is not a file")
    m = mujoco.MjModel.from_xml_path(str(args.hb_env))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.ctrl[:] = m.actuator_ctrlrange.mean(axis=1)
    fell, ret = None, 0.0
    for t in range(1, args.steps + 1):
        for _ in range(10):
            mujoco.mj_step(m, d)
        ret += sit_simple_reward(m, d)
        if fell is None and d.qpos[2] < 0.5:
            fell = t
        if t % 200 == 0:
            print(f"step {t:>5}: pelvis x {d.qpos[0]:+.3f} y {d.qpos[1]:+.3f} z {d.qpos[2]:.3f}")
    print(f"{args.hb_env.name}: zero action, {args.steps} control steps; "
          + ("never fell (pelvis >= 0.5 m)" if fell is None else f"fell at step {fell}")
          + f"; sit_simple return (spec formula, all steps) {ret:.1f}")


if __name__ == "__main__":
    main()
