"""The observation/action contract of an exported policy: what `contract.json` says, built
from the env the policy was trained on (docs/cli.md, "Export and sim-to-sim").

The contract is what a controller outside sirl_jax needs to drive the robot: the scene model
(compiled, with its hash), the control rate, the observation field by field (qpos and qvel
slices by joint, task extras), the action order by actuator and its map to ctrl, and, where
this module can describe them exactly, the reset distribution, the termination rule and the
reward. What it cannot describe is marked `not_described` with the reason, never guessed.
Its reader (`contract_sim`) uses numpy and MuJoCo only.

Only this module knows the env classes; it builds a contract for the pendulum and for the
HumanoidBench tasks (`HumanoidEnv`), and refuses other envs.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from pathlib import Path

import mujoco

from sirl_jax.run.errors import UsageError

FORMAT = "sirl_jax-policy-contract"
VERSION = 1
MODEL_FILE = "model.mjb"

_JOINT_COMPONENTS = {
    mujoco.mjtJoint.mjJNT_FREE: (("x", "y", "z", "qw", "qx", "qy", "qz"),
                                 ("vx", "vy", "vz", "wx", "wy", "wz")),
    mujoco.mjtJoint.mjJNT_BALL: (("qw", "qx", "qy", "qz"), ("wx", "wy", "wz")),
    mujoco.mjtJoint.mjJNT_SLIDE: (("pos",), ("vel",)),
    mujoco.mjtJoint.mjJNT_HINGE: (("angle",), ("angvel",)),
}  # fmt: skip


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def config_sha256(config_dict: dict) -> str:
    """Hex SHA-256 of a config as canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(config_dict, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def joint_fields(model: mujoco.MjModel) -> tuple[list[dict], list[dict]]:
    """(qpos fields, qvel fields): one per joint, in address order, with its slice."""
    qpos, qvel = [], []
    for j in range(model.njnt):
        jtype = mujoco.mjtJoint(int(model.jnt_type[j]))
        pos_names, vel_names = _JOINT_COMPONENTS[jtype]
        name = model.joint(j).name
        kind = jtype.name[6:].lower()
        qpos.append({"name": f"qpos/{name}", "source": "qpos", "joint": name, "joint_type": kind,
                     "adr": int(model.jnt_qposadr[j]), "size": len(pos_names),
                     "components": list(pos_names)})  # fmt: skip
        qvel.append({"name": f"qvel/{name}", "source": "qvel", "joint": name, "joint_type": kind,
                     "adr": int(model.jnt_dofadr[j]), "size": len(vel_names),
                     "components": list(vel_names)})  # fmt: skip
    return sorted(qpos, key=lambda f: f["adr"]), sorted(qvel, key=lambda f: f["adr"])


def _with_starts(fields: list[dict]) -> list[dict]:
    start = 0
    for f in fields:
        f["start"] = start
        start += f["size"]
    return fields


def _actuators(model: mujoco.MjModel, nu: int) -> list[dict]:
    low, high = model.actuator_ctrlrange[:nu].T
    return [{"name": model.actuator(i).name, "ctrl_low": float(low[i]),
             "ctrl_high": float(high[i])} for i in range(nu)]  # fmt: skip


def _pendulum_parts(env) -> dict:
    fields = [
        {"name": "cos_theta", "source": "cos_qpos", "adr": 0, "size": 1},
        {"name": "sin_theta", "source": "sin_qpos", "adr": 0, "size": 1},
        {"name": "theta_dot/10", "source": "qvel", "adr": 0, "size": 1, "scale": 0.1},
    ]
    return {
        "fields": fields,
        "substeps": env.n_substeps,
        "reset": {"kind": "uniform_qpos", "low": [-math.pi], "high": [math.pi], "qvel": 0.0},
        "termination": {"kind": "never"},
        "reward": {"kind": "pendulum_swingup",
                   "formula": "((cos q0 + 1)/2) * ((4 + 1 - a0^2)/5) * "
                              "((1 + exp(-0.1 v0^2))/2), a clipped to [-1, 1]"},  # fmt: skip
    }


def _termination(task_id: str) -> dict:
    """The HumanoidBench termination rule of a locomotion task, where it is a state test."""
    from sirl_jax.envs.tasks import LOCOMOTION

    name = re.sub(r"^h1(hand|strong)?-|-v0$", "", task_id)
    row = next((r for r in LOCOMOTION if r.name == name), None)
    rule = row.termination if row is not None else ""
    if rule == "never":
        return {"kind": "never"}
    height = re.fullmatch(r"root z < ([0-9.]+)", rule)
    if height:
        return {"kind": "qpos_below", "adr": 2, "value": float(height.group(1)), "rule": rule}
    zz = re.fullmatch(r"torso zz < ([0-9.]+)", rule)
    if zz:
        return {"kind": "body_zz_below", "body": "torso_link", "value": float(zz.group(1)),
                "rule": rule}  # fmt: skip
    return {"kind": "not_described", "rule": rule or "unknown",
            "why": "the rule reads contacts or task state, which the contract does not carry"}


def _humanoid_parts(env, task_id: str) -> dict:
    from sirl_jax.envs.humanoid import FRAME_SKIP
    from sirl_jax.envs.rewards import STAND_HEIGHT
    from sirl_jax.envs.tasks.locomotion.basic import WalkTask

    task = env.task
    fields = task.extra_obs_fields()
    if fields is None:
        fields = [{"name": f"task/{task.name}", "source": "task",
                   "size": int(task.extra_obs_size),
                   "why": f"{type(task).__name__}.extra_obs: task code"}]  # fmt: skip
    reset = {"kind": "keyframe_noise", "keyframe": "stand", "qpos_noise": task.reset_noise,
             "qvel": 0.0}  # fmt: skip
    ops = task.reset_ops()
    if ops is None:
        reset = {"kind": "not_described", "why": f"{type(task).__name__}'s reset does what "
                 "the contract's reset ops cannot say (task code)", "base": reset}  # fmt: skip
    elif ops:
        reset["then"] = ops
    if isinstance(task, WalkTask):
        reward = {"kind": "h1_walk", "speed": task.speed, "stand_height": STAND_HEIGHT,
                  "formula": "small_control * standing * upright(0.9) * (dont_move if "
                             "speed == 0 else move(speed)), HumanoidBench"}  # fmt: skip
    else:
        reward = {"kind": "not_described",
                  "why": f"{type(task).__name__}'s reward reads contacts or task state"}
    termination = task.termination_rule() or _termination(task_id)
    return {"fields": fields, "substeps": FRAME_SKIP, "reset": reset,
            "termination": termination, "reward": reward}  # fmt: skip


def env_parts(env, task_id: str) -> dict:
    """The env-specific parts of a contract (obs fields after qpos/qvel, substeps, reset,
    termination, reward); UsageError for an env this module has no contract for."""
    from sirl_jax.envs.classic import PendulumSwingup
    from sirl_jax.envs.humanoid import HumanoidEnv

    if isinstance(env, PendulumSwingup):
        return _pendulum_parts(env)
    if isinstance(env, HumanoidEnv):
        parts = _humanoid_parts(env, task_id)
        qpos, qvel = joint_fields(env.mj_model)
        if not env.task.full_state_obs:  # the robot's joints only (it owns qpos[:nq_robot])
            qpos = [f for f in qpos if f["adr"] < env.robot.nq_robot]
            qvel = [f for f in qvel if f["adr"] < env.robot.nv_robot]
        parts["fields"] = qpos + (qvel if env.task.qvel_obs else []) + parts["fields"]
        return parts
    raise UsageError(f"task {task_id} ({type(env).__name__}) has no observation contract; "
                     "export supports the pendulum and the HumanoidBench tasks")  # fmt: skip


def build_contract(env, spec, config_dict: dict | None, env_steps: int, model_path: Path) -> dict:
    """The contract of a policy trained on `env` (its scene saved at `model_path`);
    `config_dict` None: no policy (sim2sim's random policy), `training` is null."""
    model = env.mj_model
    parts = env_parts(env, spec.id)
    fields = _with_starts(parts["fields"])
    size = sum(f["size"] for f in fields)
    if size != env.observation_size:
        raise UsageError(f"task {spec.id}: the contract's fields cover {size} observation "
                         f"entries, the env observes {env.observation_size}")  # fmt: skip
    substeps = int(parts["substeps"])
    control_dt = float(model.opt.timestep) * substeps
    if not math.isclose(control_dt, env.control_dt, rel_tol=1e-9):
        raise UsageError(f"task {spec.id}: timestep x substeps = {control_dt} s, the env's "
                         f"control step is {env.control_dt} s")  # fmt: skip
    source = getattr(getattr(env, "robot", None), "variant", None)
    robot = {}
    if source is not None:
        from sirl_jax.envs.h1 import ASSET_DIR, VARIANTS

        xml = ASSET_DIR / VARIANTS[source]
        robot = {"robot_source": f"assets/h1_shadow/{xml.name}",
                 "robot_source_sha256": sha256_file(xml)}  # fmt: skip
    return {
        "format": FORMAT,
        "version": VERSION,
        "task": {"id": spec.id, "episode_length": int(env.episode_length),
                 "success_bar": env.success_bar},  # fmt: skip
        "training": None if config_dict is None else {
            "config_file": "config.json", "config_sha256": config_sha256(config_dict),
            "env_steps": int(env_steps)},  # fmt: skip
        "model": {"file": model_path.name, "format": "mjb", "sha256": sha256_file(model_path),
                  "mujoco_version": mujoco.__version__, "nq": int(model.nq),
                  "nv": int(model.nv), "nu": int(model.nu), **robot},  # fmt: skip
        "timing": {"timestep": float(model.opt.timestep), "substeps": substeps,
                   "control_dt": control_dt, "control_hz": 1.0 / control_dt},  # fmt: skip
        "observation": {"size": size, "dtype": "float32", "fields": fields},
        "action": {
            "size": int(env.action_size),
            "range": [-1.0, 1.0],
            "to_ctrl": "ctrl[i] = ctrl_low[i] + (a[i] + 1) / 2 * (ctrl_high[i] - ctrl_low[i]), "
            "held for `substeps` physics steps; MuJoCo clamps ctrl to ctrlrange",
            "actuators": _actuators(model, int(env.action_size)),
        },
        "reset": parts["reset"],
        "termination": parts["termination"],
        "reward": parts["reward"],
    }


def write_model(env, path: Path) -> None:
    """Writes the env's compiled scene (`mj_model`) as MuJoCo's binary model file."""
    if getattr(env, "mj_model", None) is None:
        raise UsageError(f"{type(env).__name__} has no MuJoCo model to export")
    mujoco.mj_saveModel(env.mj_model, str(path), None)


def write_contract(contract: dict, path: Path) -> None:
    path.write_text(json.dumps(contract, indent=1, sort_keys=False) + "\n")
