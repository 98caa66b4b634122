"""Solver settings vs accuracy: each candidate against MuJoCo C at HumanoidBench's settings.

Same model (h1hand, locomotion contacts), same action sequences; reference = MuJoCo C with
Newton 100 iterations / 50 line-search iterations and eulerdamp on (HumanoidBench). For each
candidate (MuJoCo C, and MJX for the candidates listed in --mjx) it reports:

  smooth: max |qpos - qpos_ref| over 50 control steps of small smooth actions (0.05 amplitude,
          1 Hz, around the keyframe-holding action), and the same for the root height;
  stand:  seconds until the pelvis drops below 0.2 m when holding the keyframe action
          (HumanoidBench: about 1.5-2 s).

Run: .venv/bin/python -m experiments.fidelity.robot_solver_accuracy [--mjx 1,5,0 2,6,1]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.envs import control_step, h1
from sirl_jax.run.compile_cache import enable_compilation_cache

N_STEPS = 50
STAND_SECONDS = 3.0
CANDIDATES = [(1, 5, 0), (1, 5, 1), (2, 6, 0), (2, 6, 1), (4, 8, 1), (10, 20, 1)]


def configured_model(iterations: int, ls_iterations: int, eulerdamp: int) -> mujoco.MjModel:
    model = h1.load_model("h1hand")
    model.opt.iterations, model.opt.ls_iterations = iterations, ls_iterations
    if eulerdamp:
        model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)
    else:
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)
    return model


def smooth_actions(robot: h1.Robot, n_steps: int) -> np.ndarray:
    """[n_steps, A] small smooth actions around the keyframe-holding action."""
    t = np.arange(n_steps)[:, None] * h1.CONTROL_DT
    phase = np.linspace(0, 2 * np.pi, robot.nu, endpoint=False)[None]
    return np.clip(robot.keyframe_action[None] + 0.05 * np.sin(2 * np.pi * t + phase), -1, 1)


def rollout_c(model: mujoco.MjModel, ctrls: np.ndarray) -> np.ndarray:
    """[T, nq] qpos after each control step in MuJoCo C."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    out = []
    for ctrl in ctrls:
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data, nstep=h1.N_SUBSTEPS)
        out.append(data.qpos.copy())
    return np.array(out)


def rollout_mjx(model: mujoco.MjModel, ctrls: np.ndarray) -> np.ndarray:
    """[T, nq] qpos after each control step in MJX (one jitted scan over the whole sequence)."""
    mx = mjx.put_model(model)
    stepper = control_step.make_control_step()

    @jax.jit
    def run(d, ctrls):
        def body(d, c):
            d = stepper(mx, d, c)
            return d, d.qpos

        return jax.lax.scan(body, d, ctrls)[1]

    return np.asarray(run(h1.keyframe_data(model, mx), jnp.asarray(ctrls, jnp.float32)))


def fall_time(qpos: np.ndarray) -> float:
    below = np.nonzero(qpos[:, 2] < 0.2)[0]
    return float((below[0] + 1) * h1.CONTROL_DT) if below.size else float("inf")


def with_self_collision(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy whose robot colliders (hands included) also collide with each other."""
    spec = h1.robot_spec("h1hand", "manipulation")
    for geom in spec.geoms:
        if geom.contype == h1.ROBOT_CONTYPE:
            geom.contype = geom.conaffinity = h1.ROBOT_CONTYPE | h1.ROBOT_CONAFFINITY
    for p in ("lh", "rh"):  # HumanoidBench's four excludes
        side = "left" if p == "lh" else "right"
        spec.add_exclude(bodyname1=f"{p}_wrist", bodyname2=f"{side}_elbow_link")
        spec.add_exclude(bodyname1=f"{p}_thproximal", bodyname2=f"{p}_thmiddle")
    out = spec.compile()
    out.opt.iterations, out.opt.ls_iterations = model.opt.iterations, model.opt.ls_iterations
    out.opt.disableflags = model.opt.disableflags
    return out


def random_episodes(model: mujoco.MjModel, n_episodes: int, seed: int = 0) -> tuple[float, float]:
    """HumanoidBench random policy: U(-1, 1) actions, reset noise U(+-0.01) on qpos.

    Returns (mean episode length in control steps until qpos[2] < 0.2 (cap 1000), fraction of
    control steps that end with a robot-robot contact).
    """
    rng = np.random.default_rng(seed)
    robot = h1.Robot(model)
    low, high = np.asarray(robot.ctrl_low), np.asarray(robot.ctrl_high)
    data = mujoco.MjData(model)
    lengths, self_steps, steps = [], 0, 0
    for _ in range(n_episodes):
        mujoco.mj_resetDataKeyframe(model, data, 0)
        data.qpos[:] += rng.uniform(-0.01, 0.01, model.nq)
        length = 1000
        for t in range(1000):
            data.ctrl[:] = low + (rng.uniform(-1, 1, robot.nu) + 1) / 2 * (high - low)
            mujoco.mj_step(model, data, nstep=h1.N_SUBSTEPS)
            geoms = data.contact.geom[: data.ncon]
            self_steps += bool(np.any(np.all(model.geom_bodyid[geoms] != 0, axis=1)))
            steps += 1
            if data.qpos[2] < 0.2:
                length = t + 1
                break
        lengths.append(length)
    return float(np.mean(lengths)), self_steps / steps


def deviations(n_episodes: int) -> None:
    """Self-collision off (ours) vs on, MuJoCo C, random actions (HumanoidBench walk: ~50-60)."""
    base = h1.load_model("h1hand", "manipulation")
    print("\nrandom-policy episodes (MuJoCo C, manipulation contacts, 1/5 solver as shipped)")
    print("| self-collision | mean episode length | steps with robot-robot contact |")
    print("|---|---|---|")
    for name, model in (("off (shipped)", base), ("on", with_self_collision(base))):
        length, frac = random_episodes(model, n_episodes)
        print(f"| {name} | {length:.1f} | {100 * frac:.1f} % |")
    ref = configured_model(100, 50, 1)
    length, _ = random_episodes(ref, n_episodes)
    print(f"| off, Newton 100/50 + eulerdamp (locomotion contacts) | {length:.1f} | - |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mjx", nargs="*", default=["1,5,0", "2,6,1"], help="it,ls,eulerdamp")
    parser.add_argument("--episodes", type=int, default=30, help="random-policy episodes")
    args = parser.parse_args()
    enable_compilation_cache()
    robot = h1.Robot(h1.load_model("h1hand"))
    smooth = np.asarray(robot.action_to_ctrl(jnp.asarray(smooth_actions(robot, N_STEPS))))
    hold = np.asarray(robot.action_to_ctrl(jnp.asarray(robot.keyframe_action)))
    stand = np.repeat(hold[None], int(STAND_SECONDS / h1.CONTROL_DT), axis=0)
    ref_model = configured_model(100, 50, 1)
    ref_smooth, ref_stand = rollout_c(ref_model, smooth), rollout_c(ref_model, stand)
    print("reference: MuJoCo C, Newton 100/50, eulerdamp on")
    print(f"  stand: falls at {fall_time(ref_stand):.2f} s")
    print(
        "| engine | iterations/ls | eulerdamp | max qpos err vs reference (50 steps) "
        "| root z err | stand (s) | max qpos err vs C at the same settings |"
    )
    print("|---|---|---|---|---|---|---|")
    runs = [("C", c) for c in CANDIDATES]
    runs += [("MJX", tuple(int(x) for x in s.split(","))) for s in args.mjx]
    for engine, (it, ls, ed) in runs:
        model = configured_model(it, ls, ed)
        rollout = rollout_c if engine == "C" else rollout_mjx
        t0 = time.perf_counter()
        q_smooth, q_stand = rollout(model, smooth), rollout(model, stand)
        err = np.abs(q_smooth - ref_smooth).max()
        same = np.abs(q_smooth - rollout_c(model, smooth)).max()  # vs C at these settings
        z_err = np.abs(q_smooth[:, 2] - ref_smooth[:, 2]).max()
        print(
            f"| {engine} | {it}/{ls} | {'on' if ed else 'off'} | {err:.2e} | {z_err:.2e} "
            f"| {fall_time(q_stand):.2f} | {same:.1e} |   ({time.perf_counter() - t0:.0f} s)"
        )
    deviations(args.episodes)


if __name__ == "__main__":
    main()
