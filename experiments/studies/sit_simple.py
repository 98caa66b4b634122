"""The sit_simple study: TD-MPC2 (beta 0) against TDMPBC (beta 1) on h1hand-sit_simple-v0.

    .venv/bin/python -m experiments.studies.sit_simple --pilot e8-utd025   # one pilot config
    .venv/bin/python -m experiments.studies.sit_simple --arm tdmpc2        # a study arm, 3 seeds
    .venv/bin/python -m experiments.studies.sit_simple --report            # tables from the CSVs
    .venv/bin/python -m experiments.studies.sit_simple --random-episodes 64  # the random baseline

The pilot picks the config that learns most per CPU hour on a 2-core machine: each pilot
config trains one seed (beta 0) for the same budget of process CPU time (`--budget-cpu-s`,
evaluations excluded), evaluated (planner, eval mode, 4 episodes) every 5k env steps. CPU time,
not wall-clock, is the unit so that configs run side by side, or beside other work, compare
fairly. Every run resumes where it stopped (`experiments.paper.common.run_arm`) and writes
train.csv / eval.csv incrementally under `--results`.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import jax
import tyro

from experiments.paper.common import run_arm
from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import load
from sirl_jax.evaluate import make_random_evaluate
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.runlog import CsvLog

TASK = "h1hand-sit_simple-v0"
ARMS = {"tdmpc2": 0.0, "tdmpbc": 1.0}

# name -> (agent fields over `AgentConfig.small`, the `cpu` preset's agent: latent 64, MLP 128,
# encoder 64, 2 Qs, MPPI 64 x 2, batch 64; train fields). Seed steps: one episode length per env.
PILOTS: dict[str, tuple[dict, dict]] = {
    "e8-utd025": ({}, dict(num_envs=8, utd=0.25, seed_steps=8_000)),
    "e4-utd1": ({}, dict(num_envs=4, utd=1.0, seed_steps=4_000)),
    "e4-utd1-1M": (dict(model_size="1M", latent_dim=None, mlp_dim=None, enc_dim=None,
                        num_q=None, batch_size=256), dict(num_envs=4, utd=1.0, seed_steps=4_000)),
    "e4-utd1-mppi256x4": (dict(num_samples=256, num_elites=64, num_pi_trajs=24, iterations=4),
                          dict(num_envs=4, utd=1.0, seed_steps=4_000)),
}  # fmt: skip


STUDY_ENV = dict(hand_floor="none", contact_set="reduced", contact_budget=0)
"""The env the committed pilots and 100k study ran on: before the hands touched the floor and
the chair touched the whole robot (docs/tasks.md, "Hands on the floor"), so the commands of
docs/results/sit_simple_study.md reproduce its numbers."""
ENV_SETS: dict[str, dict] = {"reduced": STUDY_ENV, "hb": {}}
"""--env-set: "reduced" (`STUDY_ENV`: the pilots and the 100k study) or "hb" (the task's
defaults, HumanoidBench's contacts: the hands on the floor, the chair against the whole robot,
the locomotion contact budget; the 200k run)."""


def config(pilot: str, beta: float, steps: int, eval_every: int = 5_000,
           env_set: str = "reduced") -> Config:  # fmt: skip
    """The named pilot config at `beta`, `steps` env steps per seed, evaluated every
    `eval_every` env steps (the pilots: 5k; the study: 10k, what the issue asks), on the env
    of `env_set` (`ENV_SETS`)."""
    if pilot not in PILOTS:
        raise SystemExit(f"error: pilot {pilot!r} is unknown; allowed: {', '.join(PILOTS)}")
    agent, train = PILOTS[pilot]
    return Config(
        agent=AgentConfig.small(**agent, sirl=SirlConfig(beta=beta)),
        train=TrainConfig(task=TASK, steps=steps, chunk_steps=50, buffer_size=steps,
                          eval_every=eval_every, eval_episodes=4,
                          **train, **env_options(env_set)),
    )  # fmt: skip


def env_options(env_set: str) -> dict:
    """The env options of `env_set`; an unknown name exits naming the allowed ones."""
    if env_set not in ENV_SETS:
        raise SystemExit(f"error: --env-set {env_set!r} is unknown; allowed: "
                         f"{', '.join(ENV_SETS)}")  # fmt: skip
    return ENV_SETS[env_set]


@dataclasses.dataclass(frozen=True)
class Args:
    pilot: str | None = None
    """Run (or resume) one pilot config: one seed, beta 0, --budget-cpu-s of training."""
    arm: str | None = None
    """tdmpc2 (beta 0) or tdmpbc (beta 1): run (or resume) that study arm at --study-config."""
    report: bool = False
    """Print the pilot and study tables from the CSVs."""
    random_episodes: int = 0
    """> 0: measure the uniform random policy's return over this many episodes (one jitted
    rollout, every episode from its own reset) and write results/.../random.json."""
    zero_episodes: int = 0
    """> 0: the same for the zero-action policy (standing still), results/.../zero_action.json."""
    study_config: str = "e4-utd1"
    """The pilot config the study runs at (the pilot's winner, docs/results/sit_simple_study.md)."""
    budget_cpu_s: float = 2400.0
    seeds: int = 3
    steps: int = 100_000
    results: str = "results/sit_simple"
    env_set: str = "reduced"
    """The env of the arms and baselines (`ENV_SETS`): "reduced" (the pilots and the 100k
    study) or "hb" (HumanoidBench's contacts, the task's defaults; the 200k run)."""


def report(root: Path) -> None:
    for d in sorted(p for p in root.glob("*/*") if (p / "eval.csv").exists()):
        rows = CsvLog(d / "eval.csv").rows()
        print(f"{d.relative_to(root)}:")
        for r in rows:
            print(f"  seed {r['seed']} step {int(r['env_steps']):>7,}"
                  f" cpu {float(r['cpu_s']):>7.0f} s wall {float(r['wall_s']):>6.0f} s"
                  f" planner {r['planner_return']:>7}"
                  f" prior {r['policy_return']:>7} len {r['planner_length']}")


def random_baseline(episodes: int, out: Path, action: str = "uniform",
                    env_set: str = "reduced") -> dict:  # fmt: skip
    """A baseline policy on the task's env of `env_set` (`action`: uniform random, or zero =
    standing still): mean and std of the return over `episodes`."""
    enable_compilation_cache()
    evaluate = make_random_evaluate(load(TASK, **env_options(env_set))[1], episodes, action)
    m = jax.device_get(jax.jit(evaluate)(jax.random.PRNGKey(0)))
    p = "eval/random" if action == "uniform" else "eval/zero"
    result = {"task": TASK, "policy": action, "episodes": episodes, "env_set": env_set,
              "mean": float(m[f"{p}_return"]), "std": float(m[f"{p}_return_std"]),
              "mean_length": float(m[f"{p}_length"]),
              "blowups": int(m[f"{p}_blowups"])}  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"{action} policy on {TASK}: {result['mean']:.2f} +- {result['std']:.2f} over "
          f"{episodes} episodes (mean length {result['mean_length']:.1f}) -> {out}")
    return result


def main(args: Args) -> None:
    root = Path(args.results)
    env_options(args.env_set)  # a bad name exits before anything is built
    if args.pilot:
        cfg = config(args.pilot, 0.0, args.steps, env_set=args.env_set)
        run_arm(cfg, 1, root / "pilot" / args.pilot, f"pilot {args.pilot}",
                budget_cpu_s=args.budget_cpu_s)
    if args.arm:
        if args.arm not in ARMS:
            raise SystemExit(f"error: --arm {args.arm!r} is unknown; allowed: {', '.join(ARMS)}")
        cfg = config(args.study_config, ARMS[args.arm], args.steps, eval_every=10_000,
                     env_set=args.env_set)  # fmt: skip
        run_arm(cfg, args.seeds, root / "study" / args.arm, f"study {args.arm}")
    if args.random_episodes:
        random_baseline(args.random_episodes, root / "random.json", env_set=args.env_set)
    if args.zero_episodes:
        random_baseline(args.zero_episodes, root / "zero_action.json", "zero", args.env_set)
    if args.report:
        report(root)


if __name__ == "__main__":
    main(tyro.cli(Args))
