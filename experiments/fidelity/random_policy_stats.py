"""Random-action statistics of the locomotion and manipulation tasks, beside HumanoidBench's.

For each task: E envs, one step with a = 0 from the reset (its mean reward is HumanoidBench's
"initial per-step reward at a = 0"), then T - 1 steps of uniform random actions in [-1, 1] with
auto-resets. Reports the mean length of the episodes that terminated within the T steps, the
number of them, the mean per-step reward under random actions, and the mean return of the
episodes that ended (terminated or truncated) within the T steps (`--steps` at least the
episode length counts full-length episodes too). Manipulation tasks run on their own variant
(h1hand; h1strong for highbar_hard).

    .venv/bin/python -m experiments.fidelity.random_policy_stats [--variant h1hand] [--num-envs 64]
        [--steps 200] [--tasks walk,stand] [--budget-s 1800]

The HumanoidBench numbers (spec §3 and §7: 1000-step runs, seed 0, MuJoCo C) are printed beside
each row. Tasks are run in order until the time budget is spent; the rest are listed as skipped.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import sirl_jax.envs.tasks as tasks
from sirl_jax.envs.base import VecEnv
from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.run.compile_cache import enable_compilation_cache

# HumanoidBench reference: mean episode length, mean random reward, reward at a = 0.
REFERENCE = {
    "walk": ("~50-60", "0.09", "0.174"),
    "stand": ("~50-60", "0.35", "0.953"),
    "run": ("~50-60", "", ""),
    "stair": ("~50-60", "", ""),
    "slide": ("~50-60", "", ""),
    "pole": ("~50-60", "", ""),
    "balance_simple": ("~20", "", ""),
    "balance_hard": ("~20", "", ""),
    "reach": ("never ends", "", ""),
    "crawl": ("never ends", "", ""),
}


def random_rollout(env: HumanoidEnv, num_envs: int, steps: int):
    """A jitted `run(mx, key) -> (reward, terminated, last_length, truncated)`, each [T, E]."""

    def run(mx, key):
        venv = VecEnv(env.with_model(mx), num_envs)
        key_reset, key_act = jax.random.split(key)
        state = venv.reset(key_reset)

        def body(state, inputs):
            t, k = inputs
            a = jax.random.uniform(k, (num_envs, env.action_size), minval=-1.0, maxval=1.0)
            state = venv.step(state, jnp.where(t == 0, 0.0, a))
            return state, (state.reward, state.terminated, state.last_length, state.truncated)

        inputs = (jnp.arange(steps), jax.random.split(key_act, steps))
        _, out = jax.lax.scan(body, state, inputs)
        return out

    return jax.jit(run)


def episode_returns(reward: np.ndarray, done: np.ndarray) -> np.ndarray:
    """Returns of the episodes that end within the trace ([T, E] reward and done flags)."""
    out = []
    for e in range(reward.shape[1]):
        total = 0.0
        for t in range(reward.shape[0]):
            total += float(reward[t, e])
            if done[t, e]:
                out.append(total)
                total = 0.0
    return np.asarray(out)


def summarise(
    reward: np.ndarray,
    terminated: np.ndarray,
    last_length: np.ndarray,
    truncated: np.ndarray | None = None,
) -> dict:
    lengths = last_length[terminated]
    done = terminated if truncated is None else terminated | truncated
    returns = episode_returns(reward, done)
    return {
        "reward_a0": float(reward[0].mean()),
        "reward_random": float(reward[1:].mean()),
        "episodes": int(terminated.sum()),
        "mean_length": float(lengths.mean()) if lengths.size else float("nan"),
        "ended": int(returns.size),
        "mean_return": float(returns.mean()) if returns.size else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="h1hand", choices=tasks.VARIANTS)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--tasks", default="", help="comma-separated task names (default: all)")
    parser.add_argument("--budget-s", type=float, default=1800.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    enable_compilation_cache()
    rows = {r.name: r for r in (*tasks.LOCOMOTION, *tasks.MANIPULATION)}
    chosen = [n for n in args.tasks.split(",") if n] or list(rows)
    unknown = sorted(set(chosen) - set(rows))
    if unknown:
        raise SystemExit(f"unknown tasks {unknown}; allowed: {list(rows)}")
    print(f"variant {args.variant}, E = {args.num_envs}, T = {args.steps} steps, seed {args.seed}")
    header = (f"{'task':<16}{'episodes':>9}{'mean len':>10}{'HB len':>12}{'r random':>10}"
              f"{'HB':>6}{'r(a=0)':>8}{'HB':>7}{'ended':>7}{'return':>9}{'wall s':>8}")
    print(header)
    print("-" * len(header))
    start = time.perf_counter()
    for name in chosen:
        if time.perf_counter() - start > args.budget_s:
            print(f"{name:<16}skipped (time budget spent)")
            continue
        t0 = time.perf_counter()
        row = rows[name]
        variant = row.robot if row in tasks.MANIPULATION else args.variant
        env = HumanoidEnv(
            row.task(), variant, episode_length=row.episode_length, success_bar=row.success_bar
        )
        run = random_rollout(env, args.num_envs, args.steps)
        out = jax.device_get(run(env.mx, jax.random.PRNGKey(args.seed)))
        s = summarise(*(np.asarray(x) for x in out))
        ref = REFERENCE.get(name, ("", "", ""))
        print(f"{name:<16}{s['episodes']:>9}{s['mean_length']:>10.1f}{ref[0]:>12}"
              f"{s['reward_random']:>10.3f}{ref[1]:>6}{s['reward_a0']:>8.3f}{ref[2]:>7}"
              f"{s['ended']:>7}{s['mean_return']:>9.1f}{time.perf_counter() - t0:>8.0f}",
              flush=True)


if __name__ == "__main__":
    main()
