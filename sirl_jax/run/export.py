"""The `export` command: a checkpoint's policy and planner as files that leave the trainer.

`python -m sirl_jax export RUN_DIR [--step N] [--out DIR] [--force]` writes to DIR
(default RUN_DIR/export-<step>):

  policy.onnx    encoder + policy prior mean, obs [B, O] float32 -> action [B, A] in [-1, 1]
                 (jax2onnx, ONNX opset `OPSET`)
  planner.jax    the MPPI planner with the world model baked in, `jax.export` serialized for
                 CPU and CUDA: (obs [O], planner state [H, A], key uint32[2]) ->
                 (action [A], planner state [H, A]), eval mode; an episode starts from zeros
  params.npz     every network's params, named `<module>/<flax path>` (docs/agent.md layout)
  model.mjb      the compiled MuJoCo scene the policy was trained in
  config.json    the run's training config
  contract.json  observation/action contract (`contract.py`) and each file's SHA-256
"""

from __future__ import annotations

import dataclasses
import logging
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from sirl_jax.config import config_to_dict
from sirl_jax.run import contract as C
from sirl_jax.run import runlog
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.errors import UsageError

OPSET = 23
"""ONNX opset of policy.onnx (jax2onnx's default; Mish needs >= 18)."""
FILES = ("policy.onnx", "planner.jax", "params.npz", C.MODEL_FILE, "config.json",
         "contract.json")  # fmt: skip
PLATFORMS = ("cpu", "cuda")


def flat_params(params: dict) -> dict[str, np.ndarray]:
    """{'encoder/NormedLinear_0/Dense_0/kernel': array, ...}; 'qs/...' keep their [num_q] axis."""
    out = {}
    for path, leaf in jax.tree_util.tree_flatten_with_path(params)[0]:
        out["/".join(str(getattr(k, "key", k)) for k in path)] = np.asarray(leaf)
    return out


def nested_params(flat: dict[str, np.ndarray]) -> dict:
    """The inverse of `flat_params`: nested dicts of arrays."""
    out: dict = {}
    for name, value in flat.items():
        *parents, leaf = name.split("/")
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = jnp.asarray(value)
    return out


def planner_fn(agent, agent_state):
    """(obs [O], prev_mean [H, A], key) -> (action [A], prev_mean [H, A]): `agent.plan` for one
    env in eval mode. `first` is not an input: the warm start of a zero state is zero either
    way, so a new episode passes the zero state."""
    from sirl_jax.agent.planner import PlannerState

    def plan(obs, prev_mean, key):
        action, ps = agent.plan(agent_state, PlannerState(prev_mean[None]), obs[None],
                                jnp.zeros((1,), bool), key, eval_mode=True)  # fmt: skip
        return action[0], ps.prev_mean[0]

    return plan


def export_planner(agent, agent_state, obs_size: int, action_size: int, horizon: int):
    """`planner_fn` as a `jax.export.Exported` for `PLATFORMS` (planner.jax's program)."""
    f32 = jnp.float32
    return jax.export.export(jax.jit(planner_fn(agent, agent_state)), platforms=PLATFORMS)(
        jax.ShapeDtypeStruct((obs_size,), f32), jax.ShapeDtypeStruct((horizon, action_size), f32),
        jax.ShapeDtypeStruct((2,), jnp.uint32))  # fmt: skip


# The checkpoint leaves holding the policy's input and output layers, per learner, and how many
# outputs each action has (TD-MPC2's prior gives mu and log std).
_POLICY_LEAVES = {
    "tdmpc2": ("agent_params_encoder_NormedLinear_0_Dense_0_kernel",
               "agent_params_policy_Dense_0_kernel", 2),
    "fasttd3": ("agent_params_actor_hidden_0_kernel", "agent_params_actor_out_kernel", 1),
}  # fmt: skip


def exported_policy(cfg, action_size: int, params: dict):
    """obs [..., O] -> the eval-mode action of the policy in an export's params.npz."""
    if cfg.kind == "fasttd3":
        from sirl_jax.agent.fasttd3 import policy_from_params

        return policy_from_params(cfg, action_size, params)
    from sirl_jax.agent.networks import policy_fn

    return policy_fn(cfg, action_size, params)


def _check_obs(ckpt: Checkpointer, step: int, env, task: str, kind: str) -> None:
    shapes = ckpt.leaf_shapes(step, "state")
    first, last, per_action = _POLICY_LEAVES[kind]
    enc, pi = shapes.get(first), shapes.get(last)
    if enc is None or pi is None:
        raise UsageError(f"checkpoint {ckpt.step_dir(step)} holds no {kind} policy")
    obs_in, act_out = enc[0], pi[-1] // per_action
    if (obs_in, act_out) != (env.observation_size, env.action_size):
        raise UsageError(
            f"task {task} observes {env.observation_size} entries and takes {env.action_size} "
            f"actions, the checkpoint's policy takes {obs_in} and gives {act_out}: the task's "
            "obs is not the policy's (trained by other code?)")


def export_run(run_dir: Path, step: int | None, out: Path | None, force: bool) -> Path:
    """The body of `export`; returns the output directory. Refusals are UsageErrors."""
    try:
        from jax2onnx import to_onnx
    except ImportError as e:
        raise UsageError(f"export needs jax2onnx ({e}); install it with `make install` "
                         "(pip install --no-deps jax2onnx==0.17.1, see pyproject.toml)") from e
    # onnx_ir warns about shape-only intermediate values it leaves out of the file (the model
    # loads and runs: tests/test_export.py); the warnings say nothing to a user of the export.
    logging.getLogger("onnx_ir.serde").setLevel(logging.ERROR)
    from sirl_jax.agent import make_agent
    from sirl_jax.run.runner import load_task
    from sirl_jax.train import make_train

    if not run_dir.is_dir():
        raise UsageError(f"run directory {run_dir} does not exist")
    config = runlog.load_config(run_dir)
    if not (run_dir / "checkpoints").is_dir():  # before Checkpointer, which would create it
        raise UsageError(f"{run_dir} has no checkpoint: nothing to export")
    ckpt = Checkpointer(run_dir / "checkpoints")
    try:
        available = ckpt.steps()
        if not available:
            raise UsageError(f"{run_dir} has no checkpoint: nothing to export")
        if step is not None and step not in available:
            raise UsageError(f"--step {step}: no checkpoint at that env step; "
                             f"available: {available}")  # fmt: skip
        step = available[-1] if step is None else step
        out = run_dir / f"export-{step}" if out is None else out
        if out.exists() and not force:
            raise UsageError(f"output directory {out} exists; pass --force to write over it")
        spec, env = load_task(config.train.task, **config.train.env_options)
        C.env_parts(env, spec.id)  # refuses an env without a contract before any work
        _check_obs(ckpt, step, env, spec.id, config.agent.kind)
        train = make_train(config, env)
        key = jax.random.PRNGKey(config.train.seed)
        abstract = jax.eval_shape(train.init, key).replace(buffer=None)
        agent_state = ckpt.restore({"state": abstract}, step)["state"].agent
    finally:
        ckpt.close()
    out.mkdir(parents=True, exist_ok=True)
    cfg = dataclasses.replace(config.agent, plan_env_chunk=0)
    agent = make_agent(cfg, env.observation_size, env.action_size, env.episode_length,
                       env.success_bar)  # fmt: skip
    if cfg.kind == "fasttd3":
        from sirl_jax.agent.fasttd3 import export_params

        params = jax.device_get(export_params(agent_state))
    else:
        params = jax.device_get(agent_state.params)
    np.savez(out / "params.npz", **flat_params(params))
    O, A, H = env.observation_size, env.action_size, cfg.horizon
    to_onnx(exported_policy(cfg, A, params), [("B", O)], opset=OPSET, input_names=["obs"],
            output_names=["action"], return_mode="file",
            output_path=str(out / "policy.onnx"))  # fmt: skip
    if cfg.plans:
        (out / "planner.jax").write_bytes(export_planner(agent, agent_state, O, A, H).serialize())
    C.write_model(env, out / C.MODEL_FILE)
    config_dict = config_to_dict(config)
    runlog.write_json(out / "config.json", config_dict)
    contract = C.build_contract(env, spec, config_dict, step, out / C.MODEL_FILE)
    contract["files"] = {
        "policy.onnx": {"sha256": C.sha256_file(out / "policy.onnx"), "converter": "jax2onnx",
                        "opset": OPSET, "inputs": {"obs": ["B", O]},
                        "outputs": {"action": ["B", A]}},
        "params.npz": {"sha256": C.sha256_file(out / "params.npz"),
                       "names": "<module>/<flax path>, e.g. encoder/NormedLinear_0/Dense_0/kernel"},
        "config.json": {"sha256": C.sha256_file(out / "config.json")},
    }  # fmt: skip
    if cfg.plans:
        contract["files"]["planner.jax"] = {
            "sha256": C.sha256_file(out / "planner.jax"), "format": "jax.export",
            "platforms": list(PLATFORMS), "mode": "eval",
            "inputs": {"obs": [O], "planner_state": [H, A], "key": ["uint32", 2]},
            "outputs": {"action": [A], "planner_state": [H, A]}, "initial_state": "zeros"}
    C.write_contract(contract, out / "contract.json")
    files = [f for f in FILES if cfg.plans or f != "planner.jax"]
    print(f"exported {run_dir} env step {step:,} ({spec.id}, obs {O}, action {A}) to {out}: "
          + ", ".join(files))
    return out


def main_export(args) -> int:
    """`export` from the parsed `ExportArgs`."""
    from sirl_jax.run.compile_cache import enable_compilation_cache

    enable_compilation_cache()
    export_run(Path(args.run), args.step, None if args.out is None else Path(args.out),
               args.force)  # fmt: skip
    sys.stdout.flush()
    return 0
