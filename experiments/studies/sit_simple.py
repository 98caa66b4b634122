"""The sit_simple study: TD-MPC2 (beta 0) against TDMPBC (beta 1) on h1hand-sit_simple-v0.

    .venv/bin/python -m experiments.studies.sit_simple --pilot e8-utd025   # one pilot config
    .venv/bin/python -m experiments.studies.sit_simple --arm tdmpc2        # a study arm, 3 seeds
    .venv/bin/python -m experiments.studies.sit_simple --report            # tables from the CSVs

The pilot picks the config that learns most per CPU hour on a 2-core machine: each pilot
config trains one seed (beta 0) for the same budget of process CPU time (`--budget-cpu-s`,
evaluations excluded), evaluated (planner, eval mode, 4 episodes) every 5k env steps. CPU time,
not wall-clock, is the unit so that configs run side by side, or beside other work, compare
fairly. Every run resumes where it stopped (`experiments.paper.common.run_arm`) and writes
train.csv / eval.csv incrementally under `--results`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import tyro

from experiments.paper.common import run_arm
from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.config import Config, TrainConfig
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


def config(pilot: str, beta: float, steps: int) -> Config:
    """The named pilot config at `beta`, `steps` env steps per seed."""
    if pilot not in PILOTS:
        raise SystemExit(f"error: pilot {pilot!r} is unknown; allowed: {', '.join(PILOTS)}")
    agent, train = PILOTS[pilot]
    return Config(
        agent=AgentConfig.small(**agent, sirl=SirlConfig(beta=beta)),
        train=TrainConfig(task=TASK, steps=steps, chunk_steps=50, buffer_size=steps,
                          eval_every=5_000 if steps <= 100_000 else 10_000, eval_episodes=4,
                          **train),
    )  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Args:
    pilot: str | None = None
    """Run (or resume) one pilot config: one seed, beta 0, --budget-cpu-s of training."""
    arm: str | None = None
    """tdmpc2 (beta 0) or tdmpbc (beta 1): run (or resume) that study arm at --study-config."""
    report: bool = False
    """Print the pilot and study tables from the CSVs."""
    study_config: str = "e4-utd1"
    """The pilot config the study runs at (the pilot's winner, docs/results/sit_simple_study.md)."""
    budget_cpu_s: float = 2400.0
    seeds: int = 3
    steps: int = 100_000
    results: str = "results/sit_simple"


def report(root: Path) -> None:
    for d in sorted(p for p in root.glob("*/*") if (p / "eval.csv").exists()):
        rows = CsvLog(d / "eval.csv").rows()
        print(f"{d.relative_to(root)}:")
        for r in rows:
            print(f"  seed {r['seed']} step {int(r['env_steps']):>7,}"
                  f" cpu {float(r['cpu_s']):>7.0f} s wall {float(r['wall_s']):>6.0f} s"
                  f" planner {r['planner_return']:>7}"
                  f" prior {r['policy_return']:>7} len {r['planner_length']}")


def main(args: Args) -> None:
    root = Path(args.results)
    if args.pilot:
        cfg = config(args.pilot, 0.0, args.steps)
        run_arm(cfg, 1, root / "pilot" / args.pilot, f"pilot {args.pilot}",
                budget_cpu_s=args.budget_cpu_s)
    if args.arm:
        if args.arm not in ARMS:
            raise SystemExit(f"error: --arm {args.arm!r} is unknown; allowed: {', '.join(ARMS)}")
        cfg = config(args.study_config, ARMS[args.arm], args.steps)
        run_arm(cfg, args.seeds, root / "study" / args.arm, f"study {args.arm}")
    if args.report:
        report(root)


if __name__ == "__main__":
    main(tyro.cli(Args))
