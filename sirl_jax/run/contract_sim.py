"""An exported policy driving CPU MuJoCo (C) through its `contract.json` alone.

This module is the consumer side of `contract.py`: it imports numpy, MuJoCo and (for the
ONNX policy) onnxruntime, and no sirl_jax env or agent code, so what it does is what any
controller holding the export directory can do. The model is the export's `model.mjb`
(hash-checked); the observation, ctrl map, reset, termination and reward follow the contract.
Rewards are re-implemented here in numpy for the kinds the contract describes
(`pendulum_swingup`, `h1_walk`); for any other task the return is None (not computed).

`rollout(..., initial=...)` starts each episode from given (qpos, qvel), so the MJX side of
`sim2sim` can start from the same states.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

FORMAT, VERSION = "sirl_jax-policy-contract", 1


class ContractError(ValueError):
    """The export directory or its contract cannot drive this run (one line)."""


def read_contract(export_dir: Path) -> dict:
    """contract.json of an export directory, checked for format and version."""
    path = Path(export_dir) / "contract.json"
    if not path.is_file():
        raise ContractError(f"{export_dir} is not an export directory (no contract.json)")
    data = json.loads(path.read_text())
    if data.get("format") != FORMAT or data.get("version") != VERSION:
        raise ContractError(f"{path} is not a {FORMAT} v{VERSION} file")
    return data


def _check_hash(path: Path, sha256: str) -> None:
    if hashlib.sha256(path.read_bytes()).hexdigest() != sha256:
        raise ContractError(f"{path} does not match the SHA-256 in contract.json")


def load_model(export_dir: Path, contract: dict) -> mujoco.MjModel:
    """The scene the contract names, after checking its hash."""
    m = contract["model"]
    path = Path(export_dir) / m["file"]
    _check_hash(path, m["sha256"])
    return mujoco.MjModel.from_binary_path(str(path))


def observe(contract: dict, data: mujoco.MjData, values: dict | None = None) -> np.ndarray:
    """[O] float32 observation of `data` by the contract's fields; `values`: what the reset
    drew (`sample_initial`), for fields whose source is `reset_value`."""
    out = []
    for f in contract["observation"]["fields"]:
        adr, n, scale, src = f.get("adr", 0), f["size"], f.get("scale", 1.0), f["source"]
        if src in ("qpos", "qvel"):
            v = (data.qpos if src == "qpos" else data.qvel)[adr:adr + n]
        elif src in ("cos_qpos", "sin_qpos"):
            v = (np.cos if src == "cos_qpos" else np.sin)(data.qpos[adr:adr + n])
        elif src == "site_xpos":
            v = data.site(f["site"]).xpos
        elif src == "reset_value":
            if values is None or f["value"] not in values:
                raise ContractError(f"observation field {f['name']} reads the reset value "
                                    f"{f['value']!r}, which this episode's reset did not draw")
            v = values[f["value"]]
        else:
            raise ContractError(f"observation field {f['name']} ({src}) needs task code, which "
                                "the contract does not carry")  # fmt: skip
        out.append(np.asarray(v, np.float64) * scale)
    return np.concatenate(out).astype(np.float32)


def to_ctrl(contract: dict, action: np.ndarray) -> np.ndarray:
    """[A] action in [-1, 1] -> [A] ctrl by the contract's affine map."""
    acts = contract["action"]["actuators"]
    low = np.array([a["ctrl_low"] for a in acts])
    high = np.array([a["ctrl_high"] for a in acts])
    return low + (np.asarray(action, np.float64) + 1.0) * 0.5 * (high - low)


def sample_initial(contract: dict, model: mujoco.MjModel, rng: np.random.Generator):
    """(qpos, qvel, values) of an episode start by the contract's reset rule: the base
    distribution, then its `then` ops in order. `values` holds what `value_uniform` ops drew
    (e.g. reach's goal), which observation fields of source `reset_value` read."""
    reset = contract["reset"]
    if reset["kind"] == "uniform_qpos":
        qpos = model.qpos0.copy()
        qpos[: len(reset["low"])] = rng.uniform(reset["low"], reset["high"])
    elif reset["kind"] == "keyframe_noise":
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, reset["keyframe"])
        noise = reset["qpos_noise"]
        qpos = model.key_qpos[key] + rng.uniform(-noise, noise, model.nq)
    else:
        raise ContractError(f"the contract does not describe this task's reset: "
                            f"{reset.get('why', reset['kind'])}")  # fmt: skip
    values = {}
    for op in reset.get("then", ()):
        if op["op"] == "root_pose_uniform":  # free root: x, y and a yaw about +z
            yaw = rng.uniform(*op["yaw"])
            qpos[0], qpos[1] = rng.uniform(*op["x"]), rng.uniform(*op["y"])
            qpos[3:7] = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
        elif op["op"] == "value_uniform":
            values[op["name"]] = rng.uniform(op["low"], op["high"])
        else:
            raise ContractError(f"unknown reset op {op['op']!r} (this reader knows "
                                "root_pose_uniform, value_uniform)")
    return qpos, np.full(model.nv, float(reset["qvel"])), values


def _geom_ids(model: mujoco.MjModel, names: list[str]) -> np.ndarray:
    ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in names])
    if (ids < 0).any():
        missing = [n for n, i in zip(names, ids, strict=True) if i < 0]
        raise ContractError(f"termination rule names geoms the model lacks: {missing}")
    return ids


def _overlap_test(model: mujoco.MjModel, a: np.ndarray, b: np.ndarray) -> Callable:
    """data -> bool, some geom of `a` penetrates some geom of `b` (`mj_geomDistance` < 0).
    Pairs farther apart than their bounding spheres are skipped (a plane's sphere is
    unbounded)."""
    fromto = np.zeros(6)

    def test(data: mujoco.MjData) -> bool:
        for gb in b:
            rb = model.geom_rbound[gb]
            near = a
            if rb > 0:
                gap = np.linalg.norm(data.geom_xpos[a] - data.geom_xpos[gb], axis=-1)
                near = a[gap < model.geom_rbound[a] + rb]
            for ga in near:
                if mujoco.mj_geomDistance(model, data, int(ga), int(gb), 0.0, fromto) < 0.0:
                    return True
        return False

    return test


def _rule_fn(rule: dict, model: mujoco.MjModel) -> Callable[[mujoco.MjData], bool] | None:
    kind = rule["kind"]
    if kind == "never":
        return lambda data: False
    if kind == "qpos_below":
        return lambda data: bool(data.qpos[rule["adr"]] < rule["value"])
    if kind == "body_zz_below":
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, rule["body"])
        return lambda data: bool(data.xmat[body, 8] < rule["value"])
    if kind == "geoms_overlap":
        return _overlap_test(model, _geom_ids(model, rule["a"]), _geom_ids(model, rule["b"]))
    if kind == "any":
        parts = [_rule_fn(r, model) for r in rule["rules"]]
        if any(p is None for p in parts):
            return None
        return lambda data: any(p(data) for p in parts)
    return None  # not_described


def termination_fn(contract: dict, model: mujoco.MjModel) -> Callable[[mujoco.MjData], bool | None]:
    """data -> the contract's termination rule on it (None: the rule is not described)."""
    test = _rule_fn(contract["termination"], model)
    return (lambda data: None) if test is None else test


def terminated(contract: dict, model: mujoco.MjModel, data: mujoco.MjData) -> bool | None:
    """The contract's termination rule (None: not described)."""
    return termination_fn(contract, model)(data)


def tolerance(x, bounds=(0.0, 0.0), margin=0.0, sigmoid="gaussian", value_at_margin=0.1):
    """dm_control's `rewards.tolerance` in numpy (float64)."""
    x = np.asarray(x, np.float64)
    lower, upper = bounds
    inside = (lower <= x) & (x <= upper)
    if margin == 0:
        return np.where(inside, 1.0, 0.0)
    with np.errstate(invalid="ignore"):
        d = np.where(inside, 0.0, np.where(x < lower, lower - x, x - upper) / margin)
    if sigmoid == "gaussian":
        value = np.exp(-0.5 * (d * math.sqrt(-2.0 * math.log(value_at_margin))) ** 2)
    elif sigmoid == "linear":
        s = d * (1.0 - value_at_margin)
        value = np.where(np.abs(s) < 1.0, 1.0 - s, 0.0)
    else:  # quadratic
        s = d * math.sqrt(1.0 - value_at_margin)
        value = np.where(np.abs(s) < 1.0, 1.0 - s**2, 0.0)
    return np.where(inside, 1.0, value)


def _h1_walk(rule: dict, model: mujoco.MjModel, data: mujoco.MjData) -> float:
    h = rule["stand_height"]
    head = data.site_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "head"), 2]
    zz = data.xmat[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso_link"), 8]
    sensor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, "pelvis_subtreelinvel")
    v = data.sensordata[model.sensor_adr[sensor]:model.sensor_adr[sensor] + 3]
    force = data.actuator_force[: model.nu]
    standing = tolerance(head, (h, math.inf), margin=h / 4)
    upright = tolerance(zz, (0.9, math.inf), margin=1.9, sigmoid="linear", value_at_margin=0.0)
    small = (4.0 + np.mean(tolerance(force, margin=10.0, sigmoid="quadratic",
                                     value_at_margin=0.0))) / 5.0  # fmt: skip
    speed = rule["speed"]
    if speed == 0:
        motion = np.mean(tolerance(v[:2], margin=2.0))
    else:
        m = tolerance(v[0], (speed, math.inf), margin=speed, sigmoid="linear",
                      value_at_margin=0.0)  # fmt: skip
        motion = (5.0 * m + 1.0) / 6.0
    return float(small * standing * upright * motion)


def reward(contract: dict, model, data, action: np.ndarray) -> float | None:
    """The step's reward by the contract's reward kind, from the data after the step (None:
    the contract does not describe this task's reward)."""
    rule = contract["reward"]
    if rule["kind"] == "pendulum_swingup":
        a = float(np.clip(action[0], -1.0, 1.0))
        upright = (math.cos(data.qpos[0]) + 1.0) / 2.0
        small_velocity = (1.0 + math.exp(-0.1 * data.qvel[0] ** 2)) / 2.0
        return upright * (4.0 + (1.0 - a**2)) / 5.0 * small_velocity
    if rule["kind"] == "h1_walk":
        return _h1_walk(rule, model, data)
    return None


def onnx_policy(export_dir: Path, contract: dict) -> Callable[[np.ndarray], np.ndarray]:
    """obs [O] -> action [A] by policy.onnx on onnxruntime's CPU provider (hash-checked)."""
    import onnxruntime as ort

    path = Path(export_dir) / "policy.onnx"
    _check_hash(path, contract["files"]["policy.onnx"]["sha256"])
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return lambda obs: session.run(None, {"obs": obs[None].astype(np.float32)})[0][0]


def rollout(export_dir: Path, contract: dict, act: Callable, initial: list, max_steps: int,
            on_reset: Callable | None = None,
            on_step: Callable | None = None) -> list[dict]:  # fmt: skip
    """One episode per (qpos, qvel, values) in `initial`, on CPU MuJoCo: `act(obs) -> action`,
    ctrl held for `substeps` mj_step calls, until the contract's termination or `max_steps`
    (a rule the contract does not describe never ends an episode). `on_step(data, action)`
    sees the data after each control step (what a reward reads).

    Returns per episode: return (None if the reward is not described), length, terminated,
    obs [steps + 1, O] (the observations seen, the first one included).
    """
    model = load_model(export_dir, contract)
    data = mujoco.MjData(model)
    substeps, results = contract["timing"]["substeps"], []
    ends = termination_fn(contract, model)
    for qpos, qvel, values in initial:
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(model, data)
        if on_reset is not None:
            on_reset()
        obs = observe(contract, data, values)
        seen, ret, ended, steps = [obs], 0.0, False, 0
        for steps in range(1, max_steps + 1):  # noqa: B007
            action = np.asarray(act(obs))
            data.ctrl[: len(action)] = to_ctrl(contract, action)
            for _ in range(substeps):
                mujoco.mj_step(model, data)
            if on_step is not None:
                on_step(data, action)
            r = reward(contract, model, data, action)
            ret = None if r is None or ret is None else ret + r
            obs = observe(contract, data, values)
            seen.append(obs)
            ended = bool(ends(data))
            if ended or not np.all(np.isfinite(obs)):
                break
        results.append({"return": ret, "length": steps, "terminated": ended,
                        "obs": np.stack(seen)})  # fmt: skip
    return results
