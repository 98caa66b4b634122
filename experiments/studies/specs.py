"""Every study as a spec: a config, its arms (field overrides), its seeds and its report.

`experiments.study` runs any of them: an arm is a sweep of the study's seeds (one program, or
one seed per process), under `RESULTS/<study>/<arm>/`. The seeds' keys are
split(PRNGKey(0), seeds)[i] (`Sweep.split`), the drivers' scheme before sweeps, so that the
committed runs reproduce. Arms differ in dotted fields (`override`); where they differ only
in per-run scalars (`sirl_jax.agent.hyper.SWEEPABLE`) they could share one program, but on
this CPU processes side by side are faster (docs/cli.md, "Sweeps").
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.config import Config, TrainConfig
from sirl_jax.presets import get_preset

SIT = "h1hand-sit_simple-v0"
STUDY_ENV = dict(hand_floor="none", contact_set="reduced", contact_budget=0)
"""The env the sit_simple studies ran on: before the hands touched the floor and the chair
touched the whole robot (docs/tasks.md, "Hands on the floor"), so their numbers reproduce."""


def override(config: Config, fields: Mapping[str, Any]) -> Config:
    """`config` with each dotted field (e.g. "agent.sirl.beta") set; the dataclasses check."""

    def put(obj, path: list[str], value, field: str):
        names = {f.name for f in dataclasses.fields(obj)} if dataclasses.is_dataclass(obj) else {}
        if path[0] not in names:
            raise SystemExit(f"error: {field} is not a config field ({path[0]!r} is not one of "
                             f"{type(obj).__name__}'s: {', '.join(sorted(names))})")  # fmt: skip
        if len(path) == 1:
            return dataclasses.replace(obj, **{path[0]: value})
        inner = put(getattr(obj, path[0]), path[1:], value, field)
        return dataclasses.replace(obj, **{path[0]: inner})

    for field, value in fields.items():
        config = put(config, field.split("."), value, field)
    return config


@dataclasses.dataclass(frozen=True)
class Study:
    """config(task): the base config (its task given, or `task`); arms: {arm: overrides};
    budget_cpu_s: each run stops once its training has used this much process CPU (a pilot:
    configs compared at equal CPU); report: the command that writes its committed results."""

    doc: str
    config: Callable[[str], Config]
    arms: Mapping[str, Mapping[str, Any]]
    task: str = SIT
    seeds: int = 3
    budget_cpu_s: float | None = None
    report: str = ""
    per_task: bool = False
    """Its arms run per task (`--task`): RESULTS/<study>/<task>/<arm>."""


def fasttd3_cpu(task: str, steps: int, every: int, episodes: int, replay: str) -> Config:
    """The `fasttd3-cpu` preset (32 envs, batch 1024, critic 512, actor 256) on the study env,
    the replay holding the whole run."""
    cfg = get_preset("fasttd3-cpu")
    return override(cfg, {"agent.fasttd3.replay_sampling": replay, "train.task": task,
                          "train.steps": steps, "train.num_envs": 32, "train.buffer_size": steps,
                          "train.eval_every": every, "train.eval_episodes": episodes,
                          **{f"train.{k}": v for k, v in STUDY_ENV.items()}})  # fmt: skip


def small(task: str, steps: int, every: int, agent: Mapping = (), **train) -> Config:
    """The `cpu` preset's agent (`AgentConfig.small`: latent 64, MLP 128, 2 Qs, MPPI 64 x 2,
    batch 64) with `agent` fields; chunks of 50, the replay holding the whole run."""
    return Config(agent=AgentConfig.small(**dict(agent), sirl=SirlConfig()),
                  train=TrainConfig(task=task, steps=steps, chunk_steps=50, buffer_size=steps,
                                    eval_every=every, eval_episodes=4, **train))  # fmt: skip


def paper_scale(scale: str) -> Callable[[str], Config]:
    """paper: the 5M model, MPPI 512 x 8, 1 env, 2M steps, the fork's v1 log-prob, on h1hand;
    cpu: the `cpu` preset's agent on the hand-less h1 task, 4 envs, UTD 0.25, 80k steps."""

    def config(task: str) -> Config:
        if scale == "paper":
            return Config(agent=AgentConfig(entropy_form="v1"),
                          train=TrainConfig(task=f"h1hand-{task}-v0", steps=2_000_000))
        return small(f"h1-{task}-v0", 80_000, 20_000, num_envs=4, utd=0.25, seed_steps=5_000)

    return config


BETA = "agent.sirl.beta"
BETAS = {"beta0": {BETA: 0.0}, "beta1": {BETA: 1.0}}  # FastTD3 without and with the term
TDMPC2_ARMS = {"tdmpc2": {BETA: 0.0}, "tdmpbc": {BETA: 1.0}}  # TD-MPC2 and TDMPBC
PILOT_TDMPC2 = {  # the sit_simple pilots: agent fields over AgentConfig.small; train fields
    "e8-utd025": ({}, dict(num_envs=8, utd=0.25, seed_steps=8_000)),
    "e4-utd1": ({}, dict(num_envs=4, utd=1.0, seed_steps=4_000)),
    "e4-utd1-1M": (dict(model_size="1M", latent_dim=None, mlp_dim=None, enc_dim=None,
                        num_q=None, batch_size=256), dict(num_envs=4, utd=1.0, seed_steps=4_000)),
    "e4-utd1-mppi256x4": (dict(num_samples=256, num_elites=64, num_pi_trajs=24, iterations=4),
                          dict(num_envs=4, utd=1.0, seed_steps=4_000)),
}  # fmt: skip
RECIPES = {  # the sit_simple_solved pilot's FastTD3 fields
    "base": {"replay_sampling": "episode"},
    "ema": {"replay_sampling": "episode", "actor_ema": 0.005},
    "transition": {"replay_sampling": "transition"},
    "transition_ema": {"replay_sampling": "transition", "actor_ema": 0.005},
}


def _pilot_tdmpc2(name: str) -> Callable[[str], Config]:
    agent, train = PILOT_TDMPC2[name]
    return lambda task: small(task, 100_000, 5_000, agent, **train, **STUDY_ENV)


STUDIES: dict[str, Study] = {
    "sit_simple_solved": Study(
        "FastTD3 + the TDMPBC term past HumanoidBench's bar: 400k steps, 16 episodes every 20k",
        lambda task: fasttd3_cpu(task, 400_000, 20_000, 16, "transition"),
        BETAS,
        report="experiments.studies.sit_simple_solved_report --results results/sit_simple_solved"),
    "sit_simple_solved_pilot": Study(
        "the solved study's recipes at beta 1, one seed each at equal training CPU",
        lambda task: fasttd3_cpu(task, 300_000, 10_000, 16, "episode"),
        {name: {f"agent.fasttd3.{k}": v for k, v in fields.items()}
         for name, fields in RECIPES.items()},
        seeds=1, budget_cpu_s=2000.0,
        report="experiments.studies.sit_simple_solved_report --pilot --results "
               "results/sit_simple_solved_pilot"),
    "parallel_learner": Study(
        "FastTD3 (beta 0) against FastTD3 + SIRL (beta 1) against wall-clock, 200k steps",
        lambda task: fasttd3_cpu(task, 200_000, 10_000, 4, "episode"),
        BETAS,
        report="experiments.studies.parallel_learner --out docs/results/parallel_learner"),
    "sit_simple": Study(
        "TD-MPC2 (beta 0) against TDMPBC (beta 1) at the pilot's winner, 100k steps",
        lambda task: override(_pilot_tdmpc2("e4-utd1")(task), {"train.eval_every": 10_000}),
        TDMPC2_ARMS,
        report="experiments.studies.sit_simple_report --out docs/results/sit_simple_study"),
    "sit_simple_hb": Study(
        "the sit_simple study to 200k steps on HumanoidBench's contact set (the task defaults)",
        lambda task: override(_pilot_tdmpc2("e4-utd1")(task), {
            "train.eval_every": 10_000, "train.steps": 200_000, "train.buffer_size": 200_000,
            **{f"train.{k}": getattr(TrainConfig(), k) for k in STUDY_ENV}}),
        TDMPC2_ARMS,
        report="experiments.studies.sit_simple_report --out docs/results/sit_simple_study"),
    "sit_simple_pilot": Study(
        "TD-MPC2 configs at beta 0, one seed each at equal training CPU, 4 episodes every 5k",
        lambda task: small(task, 100_000, 5_000, **PILOT_TDMPC2["e4-utd1"][1], **STUDY_ENV),
        {name: {BETA: 0.0, **{f"agent.{k}": v for k, v in agent.items()},
                **{f"train.{k}": v for k, v in train.items()}}
         for name, (agent, train) in PILOT_TDMPC2.items()},
        seeds=1, budget_cpu_s=2400.0),
}  # fmt: skip
for _scale in ("cpu", "paper"):
    _ablations = {
        "table": ({"TDMPBC": {BETA: 1.0}, "TD-MPC2": {BETA: 0.0}},
                  "the paper's results table: TDMPBC against TD-MPC2"),
        "beta": ({f"beta={b:g}": {BETA: b} for b in (0.5, 1.0, 2.0)}, "the paper's beta ablation"),
        "g": ({"G=R_max": {"agent.sirl.g_source": "rmax"},
               "G=R_target": {"agent.sirl.g_source": "target"}},
              "the paper's G ablation: R_max against the success bar"),
    }  # fmt: skip
    for _name, (_arms, _doc) in _ablations.items():
        STUDIES[f"paper_{_name}_{_scale}"] = Study(
            f"{_doc}, {_scale} scale (--task TASK: any locomotion task's short name)",
            paper_scale(_scale), _arms, task="stand", per_task=True,
            report=f"experiments.studies.paper_report --study paper_{_name}_{_scale} "
                   "--tasks TASK ...")  # fmt: skip
STUDIES["humanoid_study"] = dataclasses.replace(
    STUDIES["paper_table_cpu"], arms=TDMPC2_ARMS, per_task=False,
    doc="TD-MPC2 against TDMPBC on h1-stand at CPU scale (paper_table_cpu's arms)",
    report="experiments.studies.paper_report --humanoid")
