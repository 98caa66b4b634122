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

from sirl_jax.envs.tasks.locomotion.sit import sit_reward


def sit_simple_reward(d: mujoco.MjData) -> float:
    """sit_simple's per-step reward of HumanoidBench's state, by the project's own `sit_reward`
    (the spec's formula of HumanoidBench's) on HumanoidBench's sites and sensors."""
    reward, _ = sit_reward(
        d.qpos[0:3], d.body("chair").xpos[:2], d.site("head").xpos[2], d.site("imu").xpos[2],
        d.body("torso_link").xmat[8], d.actuator_force, d.sensor("pelvis_subtreelinvel").data,
    )  # fmt: skip
    return float(reward)


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
        ret += sit_simple_reward(d)
        if fell is None and d.qpos[2] < 0.5:
            fell = t
        if t % 200 == 0:
            print(f"step {t:>5}: pelvis x {d.qpos[0]:+.3f} y {d.qpos[1]:+.3f} z {d.qpos[2]:.3f}")
    print(f"{args.hb_env.name}: zero action, {args.steps} control steps; "
          + ("never fell (pelvis >= 0.5 m)" if fell is None else f"fell at step {fell}")
          + f"; sit_simple return (spec formula, all steps) {ret:.1f}")


if __name__ == "__main__":
    main()
