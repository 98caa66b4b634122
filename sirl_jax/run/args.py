"""The tyro argument dataclasses of the commands.

`cli.py` parses argv with them and dispatches; each command's body lives in its own module.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated

import tyro

from sirl_jax.config import Config
from sirl_jax.run.checkpoint_files import read_best
from sirl_jax.run.errors import UsageError


@dataclasses.dataclass(frozen=True)
class TrainArgs:
    """Train a TD-MPC2 + TDMPBC agent (or FastTD3 + SIRL: --agent.kind fasttd3, or a fasttd3-*
    preset). Short flags: --task --seed --steps --num-envs
    --chunk-steps --utd --buffer-size --eval-every --checkpoint-every --log-every
    --[no-]save-buffer (train.*); --model-size --horizon --batch-size (agent.*); --beta,
    --g rmax|target, --bc-form, --[no-]sirl (agent.sirl.*)."""

    config: Annotated[Config, tyro.conf.arg(name="")]
    preset: str = "default"
    """Config the flags start from: default (reference), tdmpbc-paper, smoke (CPU, ~minute),
    cpu, gpu, gpu-fast; fasttd3-smoke, fasttd3-cpu, fasttd3-gpu (FastTD3 + SIRL). smoke, cpu
    and fasttd3-smoke are sized for the task's episode length."""
    run_dir: str | None = None
    """Run directory (default: runs/<task>-s<seed>-<UTC time>); must not exist or be empty."""
    resume: str | None = None
    """Continue the run in this directory from its latest checkpoint, with its saved config."""
    resume_step: int | None = None
    """With --resume: continue from this checkpoint (env step) instead of the latest."""
    keep: int = 3
    """Checkpoints kept by rotation (>= 2 keeps an older good one next to the newest)."""
    guard: bool = True
    """Copy the state before each chunk so that, when a chunk goes non-finite, the last good
    state is checkpointed (one extra on-device copy of the train state, buffer included)."""
    progress: bool = True
    """Show the tqdm progress bar."""
    tensorboard: bool = True
    """Write TensorBoard event files under <run_dir>/tb."""
    wandb: bool = False
    """Also log to Weights & Biases (needs `pip install wandb`)."""
    wandb_project: str = "sirl_jax"
    """W&B project name."""
    devices: int = 1
    """Split the envs, replay buffer and batch over this many local devices (one learner)."""
    seeds: int = 1
    """Train this many seeds (train.seed, +1, ...) of every sweep point as one program, each
    run in RUN_DIR/<run> (docs/cli.md, "Sweeps")."""
    sweep: tuple[str, ...] = ()
    """Per-run values, FIELD=V1,V2 (e.g. sirl.beta=0,1): one run per value and seed, in one
    program. Fields: `sirl_jax.agent.hyper.SWEEPABLE`."""



@dataclasses.dataclass(frozen=True)
class EvalArgs:
    """Evaluate every checkpoint of a run (or one): planner and policy prior in eval mode, N
    episodes each in parallel, plus the random policy; rows go to RUN_DIR/eval/*.csv."""

    run: tyro.conf.Positional[str]
    """The run directory."""
    step: int | None = None
    """Evaluate only the checkpoint at this env step."""
    best: bool = False
    """Evaluate only the checkpoint that scored best at evaluation in training."""
    episodes: int = 10
    """Episodes per checkpoint, run in parallel (the official TD-MPC2 evaluation: 10)."""


@dataclasses.dataclass(frozen=True)
class RenderArgs:
    """Write an mp4 of a run's policy (or a random one): MJX rollout, MuJoCo drawing, 50 fps."""

    run: tyro.conf.Positional[str | None] = None
    """The run directory (omit with --random --task NAME)."""
    step: int | None = None
    """The checkpoint (env step); default: the latest."""
    best: bool = False
    """The checkpoint that scored best at evaluation in training (instead of --step)."""
    episodes: int = 2
    """Episodes, rolled out in parallel and written one after the other."""
    policy: str = "planner"
    """planner (MPPI, eval mode) | prior (the policy prior's mean action)."""
    random: bool = False
    """Uniform random actions instead of a run's policy (no run needed)."""
    task: str | None = None
    """With --random: the task to render (any registered name)."""
    out: str | None = None
    """The mp4 to write (default: RUN_DIR/videos/<step>-<policy>.mp4, where `report` finds it,
    or <task>-random.mp4)."""
    max_steps: int | None = None
    """Stop each episode after this many control steps (default: the task's T)."""
    width: int = 640
    height: int = 480
    shadows: bool = False
    """--shadows: MuJoCo's shadow maps and floor reflections (about 2.5x slower without a
    GPU); by default blob shadows under the robot."""
    antialias: bool = False
    """--antialias: 4x multisampling (about 2.3x slower without a GPU, free with one)."""
    camera: str = "track"
    """track (follows the robot and the task's objects) | side | front | back | top (fixed for
    an episode, framing all of it) | a camera the task's model names."""


@dataclasses.dataclass(frozen=True)
class PlotArgs:
    """Plot runs: eval-return curves (seeds of one config as mean ± std), R_max vs return, and
    normalised scores when the runs cover several tasks."""

    runs: tyro.conf.Positional[tuple[str, ...]]
    """Run directories."""
    out: str = "plot.png"
    """The PNG to write."""
    reference: bool = False
    """Draw the published TD-MPC2 and BMPC curves of each run's task (h1hand locomotion tasks;
    others get a one-line note) under the runs' eval curves."""


@dataclasses.dataclass(frozen=True)
class ReportArgs:
    """Write one self-contained HTML page of a run (opens offline): config, evaluations over
    checkpoints, curves with the published reference, R_max, counters, cost, latest video."""

    run: tyro.conf.Positional[str]
    """The run directory."""
    out: str | None = None
    """The HTML file to write (default: RUN_DIR/report.html)."""


@dataclasses.dataclass(frozen=True)
class ExportArgs:
    """Export a checkpoint's policy prior (ONNX), MPPI planner (jax.export), params, scene
    model and observation/action contract to a directory (docs/cli.md)."""

    run: tyro.conf.Positional[str]
    """The run directory."""
    step: int | None = None
    """The checkpoint (env step); default: the latest."""
    best: bool = False
    """The checkpoint that scored best at evaluation in training (instead of --step)."""
    out: str | None = None
    """The export directory (default: RUN_DIR/export-<step>); must not exist."""
    force: bool = False
    """Write over the files of an existing export directory."""


@dataclasses.dataclass(frozen=True)
class Sim2simArgs:
    """Drive CPU MuJoCo with an export through its contract alone, and compare with MJX."""

    export: tyro.conf.Positional[str | None] = None
    """The export directory (from `export`); or none, with --task and --policy random."""
    task: str | None = None
    """Without an export: the task whose scene and contract to build (random policy only)."""
    episodes: int = 5
    """Episodes, each from the same initial state on both sides."""
    policy: str = "prior"
    """prior (policy.onnx on onnxruntime) | planner (planner.jax, eval mode) | random (uniform
    actions from the seed, the same sequence on both sides)."""
    max_steps: int | None = None
    """Stop each episode after this many control steps (default: the task's T)."""
    seed: int = 0
    """Seed of the initial states (numpy) and the planner keys."""
    mjx: bool = True
    """--no-mjx: the CPU MuJoCo side only."""
    json: str | None = None
    """Also write the figures to this JSON file."""


def with_best(args):
    """`args` (eval, render, export) with --best turned into the --step it names: the
    checkpoint the run recorded as best at evaluation (`checkpoints/best.json`)."""
    if not args.best:
        return args
    if args.step is not None:
        raise UsageError(f"--best and --step {args.step} each name a checkpoint; give one")
    if args.run is None:
        raise UsageError("--best needs a RUN_DIR: it names the run's best checkpoint")
    best = read_best(Path(args.run) / "checkpoints")
    if best is None:
        raise UsageError(f"{args.run} records no best checkpoint (checkpoints/best.json): a "
                         "run marks one at each evaluation that beats its earlier ones; this "
                         "one has not evaluated yet, or its best checkpoint is gone")  # fmt: skip
    print(f"--best: the checkpoint at env step {best['step']:,} ({best['metric']} "
          f"{best['value']:.4g})")  # fmt: skip
    return dataclasses.replace(args, step=best["step"])
