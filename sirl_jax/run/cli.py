"""The shell: `python -m sirl_jax {train,tasks,eval,render,plot,report,export,sim2sim}`
(docs/cli.md).

This module parses argv and dispatches; the run loop is `runner.py`. `train` turns the `Config`
dataclass tree into flags with tyro (`--agent.horizon 3`, `--train.num-envs 4`: every field is
settable), accepts the short flags of `SHORT_FLAGS` (`--task`, `--seed`, `--beta`, ...) and
starts from a named preset (`--preset smoke`); a CPU preset is sized for the task first
(`config_rules.fit_to_task`), and flags given override it.

Exit codes: 0 done (or stopped by Ctrl-C after saving), 1 training failure (non-finite loss or
observation, out of memory), 2 bad input (one `error:` line), 130 aborted by a second Ctrl-C.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import sys
from pathlib import Path

import tyro

from sirl_jax.config import Config, TrainConfig
from sirl_jax.presets import PRESETS
from sirl_jax.run import runlog
from sirl_jax.run.args import (
    EvalArgs,
    ExportArgs,
    PlotArgs,
    RenderArgs,
    ReportArgs,
    Sim2simArgs,
    TrainArgs,
    with_best,
)
from sirl_jax.run.checkpoint import CheckpointError
from sirl_jax.run.config_rules import check_resume, fit_to_task
from sirl_jax.run.errors import TrainingFailure, UsageError

EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_ABORTED = 0, 1, 2, 130


def _short_flags() -> dict[str, str]:
    table = {
        "--model-size": "--agent.model-size",
        "--horizon": "--agent.horizon",
        "--batch-size": "--agent.batch-size",
        "--beta": "--agent.sirl.beta",
        "--g": "--agent.sirl.g-source",
        "--bc-form": "--agent.sirl.bc-form",
        "--sirl": "--agent.sirl.enabled",
        "--no-sirl": "--agent.sirl.no-enabled",
    }
    for f in dataclasses.fields(TrainConfig):
        dashed = f.name.replace("_", "-")
        table[f"--{dashed}"] = f"--train.{dashed}"
        table[f"--no-{dashed}"] = f"--train.no-{dashed}"
    return table


SHORT_FLAGS = _short_flags()
"""Short flag -> config flag: every `train.*` field by its own name, plus the agent ones."""


# ---------------------------------------------------------------- parsing


def expand_short_flags(argv: list[str]) -> list[str]:
    """Rewrites `--seed 3` / `--seed=3` to `--train.seed 3` by `SHORT_FLAGS`; keeps the rest."""
    out = []
    for arg in argv:
        name, eq, value = arg.partition("=")
        name = name.replace("_", "-") if name.startswith("--") else name
        out.append(SHORT_FLAGS[name] + eq + value if name in SHORT_FLAGS else arg)
    return out


def _flag_value(argv: list[str], flag: str) -> str | None:
    for i, arg in enumerate(argv):
        if arg == flag and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith(flag + "="):
            return arg.split("=", 1)[1]
    return None


@contextlib.contextmanager
def _config_errors_as_usage_errors():
    """A config `__post_init__` ValueError becomes one `error:` line instead of tyro's box,
    through tyro's parse-error hook (private; without it tyro's own box is printed)."""
    errors = getattr(tyro, "_errors", None)
    hook = getattr(errors, "on_parse_error", None)
    failure = getattr(errors, "InstantiationFailure", None)

    def handle(event) -> None:
        if failure is not None and isinstance(event, failure):
            lowered = getattr(getattr(event, "argument", None), "lowered", None)
            flags = getattr(lowered, "name_or_flags", None)
            raise UsageError(f"{'/'.join(flags)}: {event.message}" if flags else event.message)

    try:
        with hook(handle) if hook is not None else contextlib.nullcontext():
            yield
    except ValueError as e:
        raise UsageError(str(e)) from e


def _base_config(argv: list[str]) -> tuple[Config, str, dict]:
    """The config the flags start from: the resumed run's, or the preset sized for the task."""
    resume, preset = _flag_value(argv, "--resume"), _flag_value(argv, "--preset")
    if resume is not None:
        if preset is not None:
            raise UsageError("--preset cannot be combined with --resume (the saved config is used)")
        if not Path(resume).is_dir():
            raise UsageError(f"--resume {resume}: no such run directory")
        return runlog.load_config(Path(resume), sweep_ok=True), "default", {}
    try:
        chosen = PRESETS[preset or "default"]
    except KeyError as e:
        raise UsageError(e.args[0]) from e
    base = chosen.factory()
    task = _flag_value(argv, "--train.task")
    if task is not None:
        with _config_errors_as_usage_errors():
            base = dataclasses.replace(base, train=dataclasses.replace(base.train, task=task))
    if not chosen.fits_task:
        return base, preset or "default", {}
    from sirl_jax.envs.loading import spec as task_spec

    try:  # the registered spec alone: nothing built (`runner.build` builds it, once)
        spec = task_spec(base.train.task)
    except KeyError as e:
        raise UsageError(e.args[0]) from e
    except ImportError as e:
        raise UsageError(f"--task {base.train.task} needs an optional package: {e}") from e
    fitted, derived = fit_to_task(base, spec.episode_length)
    return fitted, preset, derived


def parse_train_args(argv: list[str]) -> tuple[TrainArgs, dict]:
    """Parses `train` flags; returns the args and what `fit_to_task` derived (and kept).

    With --resume, refuses overrides outside `config_rules.RESUME_MUTABLE`.
    """
    argv = expand_short_flags(argv)
    base, preset, derived = _base_config(argv)
    with _config_errors_as_usage_errors():
        args = tyro.cli(TrainArgs, default=TrainArgs(config=base, preset=preset), args=argv,
                        prog="python -m sirl_jax train")  # fmt: skip
    if args.keep < 1:
        raise UsageError(f"--keep={args.keep} is invalid; allowed: an int >= 1")
    if args.resume is not None:
        try:
            check_resume(base, args.config)
        except ValueError as e:
            raise UsageError(str(e)) from e
    given = args.config.train
    kept = {k: v for k, v in derived.items() if getattr(given, k.split(".")[1]) == v[1]}
    return args, kept


# ---------------------------------------------------------------- commands


def train(args: TrainArgs, derived: dict) -> int:
    """The `train` command (`runner.train_command`; a sweep: `sweep_run.sweep_command`)."""
    from sirl_jax.run.runner import train_command
    from sirl_jax.run.sweep_run import is_sweep, sweep_command

    if is_sweep(args):
        sweep_command(args)
        return EXIT_OK

    from sirl_jax.run.videos import TrainingVideos

    train_command(args, derived, TrainingVideos)
    return EXIT_OK


def evaluate(args: EvalArgs) -> int:
    """The `eval` command: a table of every checkpoint's evaluation, appended to the run's CSV."""
    from sirl_jax.run.evaluation import eval_run

    if args.episodes < 1:
        raise UsageError(f"--episodes={args.episodes} is invalid; allowed: an int >= 1")
    args = with_best(args)
    eval_run(Path(args.run), args.step, args.episodes)
    return EXIT_OK


def render(args: RenderArgs) -> int:
    """The `render` command: the headless GL backend is chosen before MuJoCo is imported."""
    from sirl_jax.run.render import render_command, select_gl

    for name in ("max_steps", "width", "height"):
        value = getattr(args, name)
        if value is not None and value < 1:
            flag = "--" + name.replace("_", "-")
            raise UsageError(f"{flag}={value} is invalid; allowed: an int >= 1")
    render_command(with_best(args), select_gl())
    return EXIT_OK


def plot(args: PlotArgs) -> int:
    """The `plot` command (`plot.plot`); a collapse is printed as a warning line."""
    from sirl_jax.run.plot import plot as plot_runs

    if not args.runs:
        raise UsageError("plot needs at least one RUN_DIR")
    plot_runs([Path(r) for r in args.runs], Path(args.out), reference=args.reference)
    print(f"wrote {args.out}")
    return EXIT_OK


def report(args: ReportArgs) -> int:
    """The `report` command (`report.write_report`): one self-contained HTML page; of a
    sweep directory, the sweep's page (`report_sweep.write_sweep_report`)."""
    from sirl_jax.run.report import write_report
    from sirl_jax.run.report_sweep import write_sweep_report

    run, out = Path(args.run), Path(args.out) if args.out else None
    write = write_sweep_report if runlog.sweep_runs(run) else write_report
    print(f"wrote {write(run, out)}")
    return EXIT_OK


def export(args: ExportArgs) -> int:
    """The `export` command (`export.export_run`)."""
    from sirl_jax.run.export import main_export

    return main_export(with_best(args))


def sim2sim(args: Sim2simArgs) -> int:
    """The `sim2sim` command (`sim2sim.sim2sim`)."""
    from sirl_jax.run.sim2sim import main_sim2sim

    return main_sim2sim(args)


def tasks() -> int:
    """The `tasks` command: one line per registered task."""
    from sirl_jax.run.runner import print_tasks

    print_tasks()
    return EXIT_OK


USAGE = """usage: python -m sirl_jax {train,tasks,eval,render,plot,report,export,sim2sim} [flags]

  train  python -m sirl_jax train --task hurdle [--seed 1 --steps 1000000 --num-envs 4 ...]
         --preset smoke: a CPU-sized run; --resume RUN_DIR: continue; --help: every flag
  tasks  list the registered tasks and their aliases
  eval   python -m sirl_jax eval RUN_DIR [--step N] [--episodes 10]: evaluate checkpoints
  render python -m sirl_jax render RUN_DIR [--policy planner|prior] [--out FILE.mp4], or
         render --random --task NAME: an mp4 of the policy (headless)
  plot   python -m sirl_jax plot RUN_DIR... [--out FILE.png] [--reference]: curves, R_max, scores
  report python -m sirl_jax report RUN_DIR [--out FILE.html]: one self-contained HTML page
         (of a sweep directory: its arms, mean ± std over seeds)
  export python -m sirl_jax export RUN_DIR [--step N] [--out DIR]: ONNX policy, planner,
         params, scene model and observation/action contract
  sim2sim python -m sirl_jax sim2sim EXPORT_DIR [--episodes 5] [--policy prior|planner|random]:
         the export in CPU MuJoCo through its contract, against MJX; or
         sim2sim --task NAME --policy random: any task with a contract, no export needed
"""


def _dispatch(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE, end="")
        return EXIT_OK if argv else EXIT_USAGE
    command, rest = argv[0], argv[1:]
    if command == "train":
        from sirl_jax.run.videos import prepare_gl, wants_video

        if wants_video(expand_short_flags(rest), _flag_value):  # before MuJoCo is imported
            prepare_gl()
        return train(*parse_train_args(rest))
    if command == "tasks":
        return tasks()
    if command == "eval":
        return evaluate(tyro.cli(EvalArgs, args=rest, prog="python -m sirl_jax eval"))
    if command == "render":
        return render(tyro.cli(RenderArgs, args=rest, prog="python -m sirl_jax render"))
    if command == "plot":
        return plot(tyro.cli(PlotArgs, args=rest, prog="python -m sirl_jax plot"))
    if command == "report":
        return report(tyro.cli(ReportArgs, args=rest, prog="python -m sirl_jax report"))
    if command == "export":
        return export(tyro.cli(ExportArgs, args=rest, prog="python -m sirl_jax export"))
    if command == "sim2sim":
        return sim2sim(tyro.cli(Sim2simArgs, args=rest, prog="python -m sirl_jax sim2sim"))
    raise UsageError(f"unknown command {command!r}; valid commands: train, tasks, eval, render, "
                     "plot, export, sim2sim")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Runs the CLI in-process; returns the exit code (0, 1 failure, 2 bad input, 130 abort)."""
    from sirl_jax.run.buffer_memory import BufferTooLargeError

    try:
        return _dispatch(list(sys.argv[1:] if argv is None else argv))
    except SystemExit as e:  # tyro's own usage errors (2) and --help (0)
        return e.code if isinstance(e.code, int) else EXIT_USAGE
    except (UsageError, runlog.RunDirError, CheckpointError, BufferTooLargeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except TrainingFailure as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        print("aborted by a second Ctrl-C: nothing saved since the last checkpoint",
              file=sys.stderr)  # fmt: skip
        return EXIT_ABORTED


def run() -> None:
    """Process entry point (`python -m sirl_jax`, `sirl-jax`): exits with `main`'s code.
    After a second Ctrl-C it leaves at once (`os._exit`), not waiting for the interrupted
    chunk; checkpoints are renamed into place only when complete, so nothing saved is lost."""
    code = main()
    if code == EXIT_ABORTED:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    raise SystemExit(code)


__all__ = ["SHORT_FLAGS", "EvalArgs", "ExportArgs", "PlotArgs", "RenderArgs", "ReportArgs",
           "Sim2simArgs", "TrainArgs", "TrainingFailure", "UsageError", "main", "parse_train_args",
           "run"]  # fmt: skip
