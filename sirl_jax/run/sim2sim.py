"""The `sim2sim` command: an export driving CPU MuJoCo through its contract, against MJX.

`python -m sirl_jax sim2sim EXPORT_DIR [--episodes 5] [--policy prior|planner]` runs the
exported policy (policy.onnx on onnxruntime) or the exported planner (planner.jax) in CPU
MuJoCo by `contract_sim` (no sirl_jax env code), then the same policy in MJX (the task's
sirl_jax env, the prior from params.npz in JAX, or the same planner.jax) from the same
initial states and with the same planner keys, and reports both returns and lengths, their
gap, and how soon the observations part.
"""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from sirl_jax.run import contract_sim as S
from sirl_jax.run.errors import UsageError

POLICIES = ("prior", "planner")
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


def cpu_episodes(export_dir: Path, contract: dict, policy: str, initial: list, max_steps: int,
                 seed: int) -> list[dict]:  # fmt: skip
    """The CPU MuJoCo side: `contract_sim.rollout` with the ONNX prior or planner.jax."""
    if policy == "prior":
        return S.rollout(export_dir, contract, S.onnx_policy(export_dir, contract), initial,
                         max_steps)  # fmt: skip
    plan, zero = load_planner(export_dir, contract)
    box = {"state": zero, "episode": -1, "t": 0}

    def on_reset():
        box.update(state=zero, episode=box["episode"] + 1, t=0)

    def act(obs):
        key = step_key(seed, box["episode"], box["t"])
        action, box["state"] = plan(jnp.asarray(obs), box["state"], key)
        box["t"] += 1
        return np.asarray(action)

    return S.rollout(export_dir, contract, act, initial, max_steps, on_reset)


def mjx_episodes(export_dir: Path, contract: dict, policy: str, initial: list, max_steps: int,
                 seed: int) -> list[dict]:  # fmt: skip
    """The MJX side: the task's sirl_jax env from the same (qpos, qvel), one jitted scan per
    episode (`lax.map`); return and length count up to the first termination."""
    from sirl_jax.config import Config, config_from_dict
    from sirl_jax.envs import load
    from sirl_jax.run.export import nested_params, policy_fn

    export_dir = Path(export_dir)
    config = config_from_dict(Config, json.loads((export_dir / "config.json").read_text()))
    _, env = load(contract["task"]["id"])
    if policy == "prior":
        params = nested_params(dict(np.load(export_dir / "params.npz")))
        prior = policy_fn(config.agent, env.action_size, params)
        plan, zero = None, jnp.zeros((1, 1), jnp.float32)
    else:
        plan, zero = load_planner(export_dir, contract)

    def episode(xs):
        qpos, qvel, obs0, e = xs
        state = env.reset(jax.random.PRNGKey(0))
        physics = state.physics.replace(qpos=qpos, qvel=qvel)
        state = state.replace(physics=physics, obs=obs0)

        def step(carry, t):
            state, ps, done, ret, length = carry
            if plan is None:
                action = prior(state.obs)
            else:
                action, ps = plan(state.obs, ps, step_key(seed, e, t))
            state = env.step(state, action)
            alive = ~done
            ret = ret + jnp.where(alive, state.reward, 0.0)
            length = length + alive.astype(jnp.int32)
            done = done | state.terminated | ~jnp.all(jnp.isfinite(state.obs))
            return (state, ps, done, ret, length), state.obs

        init = (state, zero, jnp.zeros((), bool), jnp.zeros(()), jnp.zeros((), jnp.int32))
        (_, _, done, ret, length), obs = jax.lax.scan(step, init, jnp.arange(max_steps))
        return ret, length, done, jnp.concatenate([obs0[None], obs])

    qpos = jnp.asarray(np.stack([q for q, _ in initial]), jnp.float32)
    qvel = jnp.asarray(np.stack([v for _, v in initial]), jnp.float32)
    obs0 = jnp.asarray(np.stack([_initial_obs(export_dir, contract, q, v) for q, v in initial]))
    ret, length, done, obs = jax.device_get(jax.jit(lambda xs: jax.lax.map(episode, xs))(
        (qpos, qvel, obs0, jnp.arange(len(initial)))))  # fmt: skip
    return [{"return": float(ret[i]), "length": int(length[i]), "terminated": bool(done[i]),
             "obs": obs[i, : int(length[i]) + 1]} for i in range(len(initial))]  # fmt: skip


def _initial_obs(export_dir: Path, contract: dict, qpos, qvel) -> np.ndarray:
    import mujoco

    model = S.load_model(export_dir, contract)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    return S.observe(contract, data)


def parted_at(a: np.ndarray, b: np.ndarray) -> int | None:
    """The first control step at which two observation sequences differ by > DIVERGED."""
    n = min(len(a), len(b))
    far = np.nonzero(np.max(np.abs(a[:n] - b[:n]), axis=-1) > DIVERGED)[0]
    return int(far[0]) if len(far) else None


def sim2sim(export_dir: Path, episodes: int, policy: str, max_steps: int | None, seed: int,
            mjx: bool = True) -> dict:  # fmt: skip
    """Runs both sides; prints a table; returns the figures (per episode and means)."""
    contract = S.read_contract(export_dir)
    model = S.load_model(export_dir, contract)
    rng = np.random.default_rng(seed)
    initial = [S.sample_initial(contract, model, rng) for _ in range(episodes)]
    T = contract["task"]["episode_length"] if max_steps is None else max_steps
    cpu = cpu_episodes(export_dir, contract, policy, initial, T, seed)
    ref = mjx_episodes(export_dir, contract, policy, initial, T, seed) if mjx else None
    rows = []
    for i, c in enumerate(cpu):
        row = {"episode": i, "cpu_return": c["return"], "cpu_length": c["length"],
               "cpu_terminated": c["terminated"]}  # fmt: skip
        if ref is not None:
            m = ref[i]
            has_return = c["return"] is not None
            row.update(mjx_return=m["return"], mjx_length=m["length"],
                       mjx_terminated=m["terminated"],
                       return_gap=c["return"] - m["return"] if has_return else None,
                       first_step_obs_diff=float(np.max(np.abs(c["obs"][1] - m["obs"][1]))),
                       parted_at=parted_at(c["obs"], m["obs"]))  # fmt: skip
        rows.append(row)
    summary = _summary(rows, contract, policy, T)
    print(_table(rows, summary))
    return {"task": contract["task"]["id"], "policy": policy, "max_steps": T, "seed": seed,
            "episodes": rows, **summary}  # fmt: skip


def _mean(rows: list[dict], key: str) -> float | None:
    vals = [r[key] for r in rows if r.get(key) is not None]
    return float(np.mean(vals)) if vals and len(vals) == len(rows) else None


def _summary(rows: list[dict], contract: dict, policy: str, T: int) -> dict:
    keys = ("cpu_return", "cpu_length", "mjx_return", "mjx_length", "return_gap",
            "first_step_obs_diff")  # fmt: skip
    out = {f"mean_{k}": _mean(rows, k) for k in keys}
    if out["mean_return_gap"] is not None:
        out["mean_abs_return_gap"] = float(np.mean([abs(r["return_gap"]) for r in rows]))
    if contract["reward"]["kind"] == "not_described":
        out["return_note"] = f"return not computed: {contract['reward']['why']}"
    return out


def _fmt(x, spec: str = ".2f") -> str:
    return "n/a" if x is None else format(x, spec)


def _table(rows: list[dict], summary: dict) -> str:
    head = (f"{'ep':>3} | {'cpu return':>10} {'len':>5} | {'mjx return':>10} {'len':>5} | "
            f"{'gap':>8} | {'obs diff @1':>11} {'parted at':>9}")  # fmt: skip
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['episode']:>3} | {_fmt(r['cpu_return']):>10} {r['cpu_length']:>5} | "
            f"{_fmt(r.get('mjx_return')):>10} {r.get('mjx_length', '-'):>5} | "
            f"{_fmt(r.get('return_gap')):>8} | {_fmt(r.get('first_step_obs_diff'), '.2e'):>11} "
            f"{_fmt(r.get('parted_at'), 'd'):>9}")  # fmt: skip
    lines.append(f"mean: cpu {_fmt(summary['mean_cpu_return'])} (len "
                 f"{_fmt(summary['mean_cpu_length'], '.0f')}), mjx "
                 f"{_fmt(summary['mean_mjx_return'])} (len "
                 f"{_fmt(summary['mean_mjx_length'], '.0f')}), mean |gap| "
                 f"{_fmt(summary.get('mean_abs_return_gap'))}")  # fmt: skip
    if "return_note" in summary:
        lines.append(summary["return_note"])
    return "\n".join(lines)


def main_sim2sim(args) -> int:
    """`sim2sim` from the parsed `Sim2simArgs`."""
    if args.episodes < 1:
        raise UsageError(f"--episodes={args.episodes} is invalid; allowed: an int >= 1")
    if args.max_steps is not None and args.max_steps < 1:
        raise UsageError(f"--max-steps={args.max_steps} is invalid; allowed: an int >= 1")
    if args.policy not in POLICIES:
        raise UsageError(f"--policy {args.policy!r} is invalid; allowed: {', '.join(POLICIES)}")
    if not Path(args.export).is_dir():
        raise UsageError(f"export directory {args.export} does not exist")
    try:
        result = sim2sim(Path(args.export), args.episodes, args.policy, args.max_steps,
                         args.seed, args.mjx)  # fmt: skip
    except S.ContractError as e:
        raise UsageError(str(e)) from e
    if args.json is not None:
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
    return 0
