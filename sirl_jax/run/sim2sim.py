"""The `sim2sim` command: an export driving CPU MuJoCo through its contract, against MJX.

`python -m sirl_jax sim2sim EXPORT_DIR [--episodes 5] [--policy prior|planner|random]` runs
the exported policy (policy.onnx on onnxruntime), the exported planner (planner.jax) or a
seeded uniform-random action sequence in CPU MuJoCo by `contract_sim` (no sirl_jax env code),
then the same policy in MJX (the task's sirl_jax env, the prior from params.npz in JAX, the
same planner.jax, the same actions) from the same initial states and with the same planner
keys, and reports both returns and lengths, their gap, and how soon the observations part.
`sim2sim --task NAME --policy random` needs no export: it writes the task's scene and
contract to a temporary directory first.

The CPU side's return is the task's own reward (`Task.evaluate`, the code that scores MJX)
evaluated on the MjData after each CPU control step, recorded by the rollout and scored
after it: the driving loop stays contract-only, and the two returns are the same function
of two simulators' states. Where the contract also describes the reward (the pendulum,
stand/walk/run), its numpy value is reported beside it (`cpu_contract_return`). The means and
the printed table are `sim2sim_report.py`'s.
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from sirl_jax.run import contract_sim as S
from sirl_jax.run import sim2sim_report as report
from sirl_jax.run.errors import UsageError

POLICIES = ("prior", "planner", "random")
DIVERGED = 0.1
"""Max |obs difference| above which the two rollouts count as parted (`parted_at`)."""


def load_planner(export_dir: Path, contract: dict):
    """(jitted call (obs, state, key) -> (action, state), zero state) of planner.jax."""
    path = Path(export_dir) / "planner.jax"
    S._check_hash(path, contract["files"]["planner.jax"]["sha256"])
    exported = jax.export.deserialize(bytearray(path.read_bytes()))
    state = jnp.zeros(exported.in_avals[1].shape, jnp.float32)
    return jax.jit(exported.call), state


def step_key(seed: int, episode: int, step) -> jax.Array:
    """The planner key of one control step (the same on both sides)."""
    return jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), episode), step)


def random_actions(seed: int, episode: int, steps: int, size: int) -> np.ndarray:
    """[steps, size] float32 uniform actions in [-1, 1] of one episode (both sides)."""
    rng = np.random.default_rng([seed, episode])
    return rng.uniform(-1.0, 1.0, (steps, size)).astype(np.float32)


def cpu_episodes(export_dir: Path, contract: dict, policy: str, initial: list, max_steps: int,
                 seed: int, recorder: Recorder | None = None) -> list[dict]:  # fmt: skip
    """The CPU MuJoCo side: `contract_sim.rollout` with the ONNX prior, planner.jax or the
    seeded random actions; `recorder` keeps each step's data for `score_cpu`."""
    A = contract["action"]["size"]
    box = {"state": None, "episode": -1, "t": 0, "actions": None}
    if policy == "prior":
        prior = S.onnx_policy(export_dir, contract)
    elif policy == "planner":
        plan, zero = load_planner(export_dir, contract)

    def on_reset():
        box.update(episode=box["episode"] + 1, t=0)
        if recorder is not None:
            recorder.new_episode()
        if policy == "planner":
            box["state"] = zero
        elif policy == "random":
            box["actions"] = random_actions(seed, box["episode"], max_steps, A)

    def act(obs):
        t = box["t"]
        box["t"] += 1
        if policy == "prior":
            return prior(obs)
        if policy == "random":
            return box["actions"][t]
        action, box["state"] = plan(jnp.asarray(obs), box["state"],
                                    step_key(seed, box["episode"], t))  # fmt: skip
        return np.asarray(action)

    return S.rollout(export_dir, contract, act, initial, max_steps, on_reset, recorder)


class Recorder:
    """`rollout`'s `on_step`: copies the MjData fields an `mjx.Data` shares with it (every
    top-level field: positions, velocities, kinematics, sensors, actuator forces; not MJX's
    contact slots) after each control step, one list per episode, for `score_cpu`."""

    def __init__(self, model):
        import mujoco
        from mujoco import mjx

        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        self.template = mjx.put_data(model, data)
        # {name: mjx shape}: MjData keeps rotation matrices flat ([n, 9]), mjx.Data as [n, 3, 3]
        self.fields = {f.name: np.shape(getattr(self.template, f.name))
                       for f in dataclasses.fields(mjx.Data)
                       if f.name != "_impl" and hasattr(data, f.name)
                       and np.size(getattr(data, f.name)) ==
                       np.size(getattr(self.template, f.name))}  # fmt: skip
        self.episodes: list[list[dict]] = []

    def new_episode(self) -> None:
        self.episodes.append([])

    def __call__(self, data, action) -> None:
        del action
        self.episodes[-1].append({k: np.reshape(getattr(data, k), shape).copy()
                                  for k, shape in self.fields.items()})  # fmt: skip


def score_cpu(env, recorder: Recorder, initial: list, max_steps: int) -> list[dict]:
    """The task's reward and termination on each recorded CPU step (HumanoidEnv tasks):
    per episode the return up to the task's first termination, and that step."""
    task, robot, template = env.task, env.robot, recorder.template

    def episode(fields, task_state, length):
        def step(s, x):
            f, t = x
            d = template.replace(**{k: jnp.asarray(v, getattr(template, k).dtype)
                                    for k, v in f.items()})  # fmt: skip
            reward, done, s, _ = task.evaluate(robot, d, s)
            return s, (jnp.where(t < length, reward, 0.0), done & (t < length))

        _, (reward, done) = jax.lax.scan(step, task_state, (fields, jnp.arange(max_steps)))
        first = jnp.where(done.any(), jnp.argmax(done), length)
        ret = jnp.sum(jnp.where(jnp.arange(max_steps) <= first, reward, 0.0))
        return ret, first + jnp.where(done.any(), 1, 0), done.any()

    score = jax.jit(episode)
    out = []
    for steps, (qpos, _, values) in zip(recorder.episodes, initial, strict=True):
        pad = [steps[-1]] * (max_steps - len(steps))
        fields = {k: np.stack([s[k] for s in steps + pad]) for k in recorder.fields}
        state0 = task.reset_state(values, jnp.asarray(qpos, jnp.float32))
        ret, length, done = jax.device_get(score(fields, state0, len(steps)))
        out.append({"return": float(ret), "length": int(length), "terminated": bool(done)})
    return out


def mjx_episodes(export_dir: Path, contract: dict, policy: str, initial: list, max_steps: int,
                 seed: int, env) -> list[dict]:  # fmt: skip
    """The MJX side: the task's sirl_jax env from the same (qpos, qvel, values), one jitted
    scan per episode (`lax.map`); return and length count up to the first termination."""
    from sirl_jax.envs.humanoid import HumanoidEnv

    export_dir = Path(export_dir)
    plan, prior, zero = None, None, jnp.zeros((1, 1), jnp.float32)
    A = env.action_size
    if policy == "prior":
        from sirl_jax.config import Config, config_from_dict
        from sirl_jax.run.export import exported_policy, nested_params

        config = config_from_dict(Config, json.loads((export_dir / "config.json").read_text()))
        params = nested_params(dict(np.load(export_dir / "params.npz")))
        prior = exported_policy(config.agent, A, params)
    elif policy == "planner":
        plan, zero = load_planner(export_dir, contract)
    if policy == "random":
        actions = np.stack([random_actions(seed, e, max_steps, A) for e in range(len(initial))])
    else:  # a placeholder the scan does not read
        actions = np.zeros((len(initial), 1, A), np.float32)

    def episode(xs):
        qpos, qvel, values, obs0, acts, e = xs
        state = env.reset(jax.random.PRNGKey(0))
        physics = state.physics.replace(qpos=qpos, qvel=qvel)
        state = state.replace(physics=physics, obs=obs0)
        if isinstance(env, HumanoidEnv):
            state = state.replace(task=env.task.reset_state(values, qpos))

        def step(carry, t):
            state, ps, done, ret, length = carry
            if prior is not None:
                action = prior(state.obs)
            elif plan is not None:
                action, ps = plan(state.obs, ps, step_key(seed, e, t))
            else:
                action = acts[t]
            state = env.step(state, action)
            alive = ~done
            ret = ret + jnp.where(alive, state.reward, 0.0)
            length = length + alive.astype(jnp.int32)
            done = done | state.terminated | ~jnp.all(jnp.isfinite(state.obs))
            return (state, ps, done, ret, length), state.obs

        init = (state, zero, jnp.zeros((), bool), jnp.zeros(()), jnp.zeros((), jnp.int32))
        (_, _, done, ret, length), obs = jax.lax.scan(step, init, jnp.arange(max_steps))
        return ret, length, done, jnp.concatenate([obs0[None], obs])

    qpos = jnp.asarray(np.stack([q for q, _, _ in initial]), jnp.float32)
    qvel = jnp.asarray(np.stack([v for _, v, _ in initial]), jnp.float32)
    values = {k: jnp.asarray(np.stack([x[k] for _, _, x in initial]), jnp.float32)
              for k in initial[0][2]}  # fmt: skip
    model = S.load_model(export_dir, contract)
    obs0 = jnp.asarray(np.stack([_initial_obs(model, contract, *i) for i in initial]))
    xs = (qpos, qvel, values, obs0, jnp.asarray(actions), jnp.arange(len(initial)))
    ret, length, done, obs = jax.device_get(jax.jit(lambda xs: jax.lax.map(episode, xs))(xs))
    return [{"return": float(ret[i]), "length": int(length[i]), "terminated": bool(done[i]),
             "obs": obs[i, : int(length[i]) + 1]} for i in range(len(initial))]  # fmt: skip


def _initial_obs(model, contract: dict, qpos, qvel, values) -> np.ndarray:
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_kinematics(model, data)  # site positions of task fields
    return S.observe(contract, data, values)


def parted_at(a: np.ndarray, b: np.ndarray) -> int | None:
    """The first control step at which two observation sequences differ by > DIVERGED."""
    n = min(len(a), len(b))
    far = np.nonzero(np.max(np.abs(a[:n] - b[:n]), axis=-1) > DIVERGED)[0]
    return int(far[0]) if len(far) else None


def task_export(task: str, out: Path):
    """Writes a policy-less export of `task` (model.mjb and contract.json, `training` null) to
    `out`; returns the env."""
    from sirl_jax.run import contract as C
    from sirl_jax.run.runner import load_task

    spec, env = load_task(task)
    C.env_parts(env, spec.id)  # refuses an env without a contract
    C.write_model(env, out / C.MODEL_FILE)
    contract = C.build_contract(env, spec, None, 0, out / C.MODEL_FILE)
    C.write_contract({**contract, "files": {}}, out / "contract.json")
    return env


def sim2sim(export_dir: Path | None, episodes: int, policy: str, max_steps: int | None,
            seed: int, mjx: bool = True, task: str | None = None) -> dict:  # fmt: skip
    """Runs both sides; prints a table; returns the figures (per episode and means).
    `export_dir` None: `task`'s scene and contract in a temporary directory."""
    if export_dir is None:
        with tempfile.TemporaryDirectory() as tmp:
            env = task_export(task, Path(tmp))
            return _sim2sim(Path(tmp), episodes, policy, max_steps, seed, mjx, env)
    return _sim2sim(export_dir, episodes, policy, max_steps, seed, mjx, None)


def _env_options(export_dir: Path, contract: dict) -> dict:
    """The env options the exported run trained with (its config.json's `train.env_options`),
    so the MJX reference env is the exported model's; {} (the task's defaults) for an export
    without a training config."""
    if not contract.get("training"):
        return {}
    from sirl_jax.run.runlog import load_config

    return load_config(export_dir).train.env_options


def _sim2sim(export_dir: Path, episodes: int, policy: str, max_steps: int | None, seed: int,
             mjx: bool, env) -> dict:  # fmt: skip
    from sirl_jax.envs.humanoid import HumanoidEnv

    contract = S.read_contract(export_dir)
    model = S.load_model(export_dir, contract)
    rng = np.random.default_rng(seed)
    initial = [S.sample_initial(contract, model, rng) for _ in range(episodes)]
    T = contract["task"]["episode_length"] if max_steps is None else max_steps
    if env is None:
        from sirl_jax.envs import load

        env = load(contract["task"]["id"], **_env_options(export_dir, contract))[1]
    scored = isinstance(env, HumanoidEnv) and not env.task.reads_contact_slots
    recorder = Recorder(model) if scored else None
    cpu = cpu_episodes(export_dir, contract, policy, initial, T, seed, recorder)
    scores = score_cpu(env, recorder, initial, T) if scored else None
    ref = mjx_episodes(export_dir, contract, policy, initial, T, seed, env) if mjx else None
    described = contract["termination"]["kind"] != "not_described"
    rows = []
    for i, c in enumerate(cpu):
        row = {"episode": i, "cpu_return": c["return"], "cpu_length": c["length"],
               "cpu_terminated": c["terminated"]}  # fmt: skip
        if scores is not None:  # the task's reward and termination on the CPU states
            s = scores[i]
            row.update(cpu_return=s["return"], cpu_length=s["length"],
                       cpu_terminated=s["terminated"], cpu_contract_return=c["return"],
                       cpu_loop_length=c["length"])  # fmt: skip
            if described:  # did the contract's rule end the CPU loop where the task says?
                row["termination_agrees"] = (c["length"], c["terminated"]) == (
                    s["length"], s["terminated"])
        if ref is not None:
            m = ref[i]
            has_return = row["cpu_return"] is not None
            row.update(mjx_return=m["return"], mjx_length=m["length"],
                       mjx_terminated=m["terminated"],
                       return_gap=row["cpu_return"] - m["return"] if has_return else None,
                       first_step_obs_diff=float(np.max(np.abs(c["obs"][1] - m["obs"][1]))),
                       parted_at=parted_at(c["obs"], m["obs"]))  # fmt: skip
        rows.append(row)
    summary = report.summary(rows, contract, scored)
    print(report.table(rows, summary))
    return {"task": contract["task"]["id"], "policy": policy, "max_steps": T, "seed": seed,
            "cpu_return_source": "task" if scored else "contract", "episodes": rows,
            **summary}  # fmt: skip


def main_sim2sim(args) -> int:
    """`sim2sim` from the parsed `Sim2simArgs`."""
    if args.episodes < 1:
        raise UsageError(f"--episodes={args.episodes} is invalid; allowed: an int >= 1")
    if args.max_steps is not None and args.max_steps < 1:
        raise UsageError(f"--max-steps={args.max_steps} is invalid; allowed: an int >= 1")
    if args.policy not in POLICIES:
        raise UsageError(f"--policy {args.policy!r} is invalid; allowed: {', '.join(POLICIES)}")
    if (args.export is None) == (args.task is None):
        raise UsageError("sim2sim needs an export directory or --task NAME (not both)")
    if args.task is not None and args.policy != "random":
        raise UsageError(f"--task runs without an export, so --policy must be random "
                         f"(got {args.policy!r}); export a run for prior or planner")
    if args.export is not None and not Path(args.export).is_dir():
        raise UsageError(f"export directory {args.export} does not exist")
    export = None if args.export is None else Path(args.export)
    if (args.policy == "planner" and export is not None
            and not (export / "planner.jax").exists()):  # fmt: skip
        raise UsageError(f"{export} has no planner.jax (its agent does not plan, e.g. "
                         "agent.kind='fasttd3'); allowed --policy: prior, random")
    try:
        result = sim2sim(export, args.episodes, args.policy, args.max_steps, args.seed,
                         args.mjx, args.task)  # fmt: skip
    except S.ContractError as e:
        raise UsageError(str(e)) from e
    if args.json is not None:
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
    return 0
