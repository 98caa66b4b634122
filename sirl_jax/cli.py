"""The shell: `python -m sirl_jax {train,tasks,eval}` (see docs/cli.md).

`train` turns the `Config` dataclass tree into flags with tyro (`--agent.horizon 3`,
`--train.num-envs 4`: every field is settable), adds short flags for the common ones (`--task`,
`--seed`, `--steps`, `--num-envs`, `--model-size`, `--beta`, `--g`, ...), starts from a named
preset (`--preset smoke`), then runs the loop: call the jitted train step, log the metrics it
returns, evaluate and checkpoint at chunk boundaries. Nothing in here runs under `jit` except
the train step, its non-finite guard and `evaluate`.

Exit codes: 0 done (or stopped by Ctrl-C after saving), 1 training failure (non-finite loss or
observation, out of memory), 2 bad input (one `error:` line), 130 aborted by a second Ctrl-C.
No error path deletes or overwrites anything already saved.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import tyro

from sirl_jax import progress as prog
from sirl_jax import runlog
from sirl_jax.checkpoint import (
    Checkpointer,
    CheckpointError,
    commit,
    copy_state,
    restore_state,
    save_state,
)
from sirl_jax.config import Config, TrainConfig, get_preset

EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_ABORTED = 0, 1, 2, 130
_EVAL_STREAM = 0x6576616C  # folded into the seed so evaluation keys never meet training keys
_CPU_WARN_SECONDS = 3600.0

_AGENT_SHORT = {
    "--model-size": "--agent.model-size",
    "--horizon": "--agent.horizon",
    "--batch-size": "--agent.batch-size",
    "--beta": "--agent.sirl.beta",
    "--g": "--agent.sirl.g-source",
    "--bc-form": "--agent.sirl.bc-form",
    "--sirl": "--agent.sirl.enabled",
    "--no-sirl": "--agent.sirl.no-enabled",
}

RESUME_MUTABLE = frozenset(
    {"train.steps", "train.eval_every", "train.eval_episodes", "train.checkpoint_every",
     "train.log_every", "train.save_buffer"}
)  # fmt: skip
"""Config fields a resumed run may change; every other field must match the saved config."""


class UsageError(Exception):
    """Bad input: printed as one `error:` line, exit code 2."""


class TrainingFailure(Exception):
    """The run stopped on a failure (non-finite values, out of memory): exit code 1."""


@dataclasses.dataclass(frozen=True)
class TrainArgs:
    """Train a TD-MPC2 + TDMPBC agent. Short flags: --task --seed --steps --num-envs
    --chunk-steps --utd --buffer-size --eval-every --checkpoint-every --log-every
    --[no-]save-buffer (train.*); --model-size --horizon --batch-size (agent.*); --beta,
    --g rmax|target, --bc-form, --[no-]sirl (agent.sirl.*)."""

    config: Annotated[Config, tyro.conf.arg(name="")]
    preset: str = "default"
    """Config the flags start from: default (reference), smoke (CPU, ~minute), cpu."""
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


@dataclasses.dataclass(frozen=True)
class EvalArgs:
    """Evaluate a run's checkpoint and print its metrics as one JSON line."""

    run: str
    """The run directory."""
    step: int | None = None
    """The checkpoint (env step); default: the latest."""
    episodes: int | None = None
    """Episodes (default: the run's train.eval_episodes)."""


# ---------------------------------------------------------------- parsing


def _flag_value(argv: list[str], flag: str) -> str | None:
    for i, arg in enumerate(argv):
        if arg == flag and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith(flag + "="):
            return arg.split("=", 1)[1]
    return None


def expand_short_flags(argv: list[str]) -> list[str]:
    """Rewrites `--seed 3` / `--seed=3` to `--train.seed 3`, etc.; other args are kept."""
    table = dict(_AGENT_SHORT)
    for f in dataclasses.fields(TrainConfig):
        dashed = f.name.replace("_", "-")
        table[f"--{dashed}"] = f"--train.{dashed}"
        table[f"--no-{dashed}"] = f"--train.no-{dashed}"
    out = []
    for arg in argv:
        name, eq, value = arg.partition("=")
        name = name.replace("_", "-") if name.startswith("--") else name
        out.append(table[name] + eq + value if name in table else arg)
    return out


@contextlib.contextmanager
def _config_errors_as_usage_errors():
    """Turns a config `__post_init__` ValueError into one `error:` line instead of tyro's box.

    Uses tyro's (private, version-pinned by pyproject) parse-error hook when present.
    """
    errors = getattr(tyro, "_errors", None)
    hook = getattr(errors, "on_parse_error", None)
    failure = getattr(errors, "InstantiationFailure", None)

    def handle(event) -> None:
        if failure is not None and isinstance(event, failure):
            arg = getattr(event, "argument", None)
            flags = getattr(getattr(arg, "lowered", None), "name_or_flags", None)
            raise UsageError(f"{'/'.join(flags)}: {event.message}" if flags else event.message)

    try:
        if hook is None:
            yield
        else:
            with hook(handle):
                yield
    except ValueError as e:
        raise UsageError(str(e)) from e


def parse_train_args(argv: list[str]) -> TrainArgs:
    """Parses `train` flags; with --resume, refuses overrides outside RESUME_MUTABLE."""
    argv = expand_short_flags(argv)
    resume, preset = _flag_value(argv, "--resume"), _flag_value(argv, "--preset")
    if resume is not None:
        if preset is not None:
            raise UsageError("--preset cannot be combined with --resume (the saved config is used)")
        if not Path(resume).is_dir():
            raise UsageError(f"--resume {resume}: no such run directory")
        base = runlog.load_config(Path(resume), Config)
    else:
        try:
            base = get_preset(preset or "default")
        except KeyError as e:
            raise UsageError(e.args[0]) from e
    default = TrainArgs(config=base, preset=preset or "default")
    with _config_errors_as_usage_errors():
        args = tyro.cli(TrainArgs, default=default, args=argv, prog="python -m sirl_jax train")
    if args.keep < 1:
        raise UsageError(f"--keep={args.keep} is invalid; allowed: an int >= 1")
    if resume is not None:
        old, new = runlog.flatten_config(base), runlog.flatten_config(args.config)
        refused = [k for k in old if old[k] != new[k] and k not in RESUME_MUTABLE]
        if refused:
            detail = ", ".join(f"{k} (saved {old[k]!r}, given {new[k]!r})" for k in refused)
            allowed = ", ".join(sorted(RESUME_MUTABLE))
            raise UsageError(f"--resume cannot change {detail}; a resumed run may change {allowed}")
        if base.train.capacity != args.config.train.capacity:
            raise UsageError(
                f"--resume: --steps {args.config.train.steps:,} would change the replay capacity "
                f"min(buffer_size, steps) from {base.train.capacity:,} to "
                f"{args.config.train.capacity:,}; start a new run, or set a buffer_size <= steps "
                "when starting one you may extend"
            )
    return args


# ---------------------------------------------------------------- building blocks


def load_task(task: str):
    """(TaskSpec, Env) for a registry id or alias, or a `dmc:` / `playground:` env."""
    from sirl_jax import train as train_lib

    try:
        spec = train_lib.load_task(task)
    except KeyError as e:
        raise UsageError(e.args[0]) from e
    except ImportError as e:
        raise UsageError(f"--task {task} needs an optional package: {e}") from e
    return spec, spec.factory()


def _tree_nbytes(tree: Any) -> int:
    import jax

    return sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(tree))


# ---------------------------------------------------------------- the run loop


@dataclasses.dataclass
class _Run:
    """What the loop needs besides the state; `saved` is the newest checkpointed env step."""

    config: Config
    args: TrainArgs
    train: Any
    ckpt: Checkpointer
    log: runlog.RunLog
    bar: prog.Progress
    saved: int | None = None


def _eval_key(seed: int, env_steps: int):
    import jax

    base = jax.random.fold_in(jax.random.PRNGKey(seed), _EVAL_STREAM)
    return jax.random.fold_in(base, env_steps)


def _evaluate(run: _Run, eval_fn, state, env_steps: int) -> dict[str, float]:
    import jax

    key = _eval_key(run.config.train.seed, env_steps)
    metrics = prog.host_scalars(jax.device_get(eval_fn(state, key)))
    run.log.log("eval", env_steps, metrics)
    run.bar.write(f"eval @ {env_steps:,}: " + ", ".join(f"{k} {v:.4g}" for k, v in metrics.items()))
    return metrics


def _nonfinite_failure(run: _Run, backup, before: int, bad: list[str]) -> TrainingFailure:
    reached = before + run.train.steps_per_call
    where = f"non-finite values in the chunk ending at env step {reached:,}: {', '.join(bad)}"
    if backup is not None:
        good = save_state(run.ckpt, backup, run.config.train.save_buffer)
        return TrainingFailure(f"{where}; the last good state (env step {good:,}) is saved in "
                               f"{run.ckpt.directory} with the earlier checkpoints")  # fmt: skip
    return TrainingFailure(f"{where}; the state was not saved (--no-guard); the last checkpoint "
                           f"is env step {run.saved}")  # fmt: skip


def _oom_failure(config: Config, error: Exception, where: str) -> TrainingFailure:
    t, a = config.train, config.agent
    first = str(error).strip().splitlines()[0][:200]
    return TrainingFailure(
        f"out of device memory {where} ({first}); reduce --buffer-size (now {t.buffer_size:,}), "
        f"--num-envs ({t.num_envs}), --chunk-steps ({t.chunk_steps}), --agent.batch-size "
        f"({a.batch_size}), --agent.num-samples ({a.num_samples}) or --model-size "
        f"({a.model_size}), or pass --no-guard"
    )


def _loop(run: _Run, state) -> int:
    """Runs chunks until train.steps, a Ctrl-C or a failure; checkpoints the final state."""
    import jax

    t = run.config.train
    step_fn = jax.jit(run.train.step, donate_argnums=0)
    backup_fn = jax.jit(copy_state) if run.args.guard else (lambda s: None)
    eval_fn = jax.jit(run.train.evaluate)
    env_steps, updates = (int(x) for x in jax.device_get((state.env_steps, state.updates)))
    mean, timing = prog.MetricMean(), []  # timing: (time, env_steps) of chunks with updates
    on_cpu = jax.default_backend() == "cpu"
    with prog.StopOnSigint() as stop, contextlib.closing(run.bar):
        while env_steps < t.steps and not stop.requested:
            before, updates_before = env_steps, updates
            try:
                backup = backup_fn(state)
                state, metrics = step_fn(state)
                metrics, env_steps, updates = jax.device_get(
                    (metrics, state.env_steps, state.updates)
                )
            except jax.errors.JaxRuntimeError as e:
                if "RESOURCE_EXHAUSTED" in str(e):
                    where = f"at env step {before:,} (last checkpoint: {run.saved})"
                    raise _oom_failure(run.config, e, where) from e
                raise
            metrics, env_steps, updates = prog.host_scalars(metrics), int(env_steps), int(updates)
            bad = prog.failures(metrics)
            if bad:
                run.log.log("metrics", before + run.train.steps_per_call, metrics)
                raise _nonfinite_failure(run, backup, before, bad)
            run.bar.update(env_steps, updates, metrics)
            mean.add(metrics)
            if prog.crossed(before, env_steps, t.log_every) or env_steps >= t.steps:
                run.log.log("metrics", env_steps, {**mean.pop(), "updates": updates})
            if prog.crossed(before, env_steps, t.eval_every):
                _evaluate(run, eval_fn, state, env_steps)
            if prog.crossed(before, env_steps, t.checkpoint_every):
                run.saved = save_state(run.ckpt, state, t.save_buffer)
            if on_cpu and updates > updates_before and len(timing) < 4:
                timing.append((time.perf_counter(), env_steps))
                if len(timing) == 4:  # rate over steady chunks: skips compile and pretraining
                    (t0, s0), (t1, s1) = timing[1], timing[3]
                    eta = (t.steps - env_steps) * (t1 - t0) / max(s1 - s0, 1)
                    if eta > _CPU_WARN_SECONDS:
                        run.bar.write(
                            f"CPU only: ~{prog.format_duration(eta)} more for "
                            f"{t.steps:,} steps; use --preset smoke or a GPU"
                        )
    if stop.requested and env_steps < t.steps and mean.pending():
        run.log.log("metrics", env_steps, {**mean.pop(), "updates": updates})
    run.saved = save_state(run.ckpt, state, t.save_buffer)
    how = "stopped (Ctrl-C/SIGTERM)" if env_steps < t.steps else "done"
    print(f"{how} at env step {env_steps:,}; checkpoint saved in {run.ckpt.directory}"
          + (f"; continue with: python -m sirl_jax train --resume {run.log.run_dir}"
             if env_steps < t.steps else ""))  # fmt: skip
    return EXIT_OK


def _timed_cost_line(trainer, state) -> str:
    """Times one act and one update call of this run's agent and says what the rest costs.

    Used on CPU-only machines for non-tiny models, before the first chunk: compiling both
    takes seconds, and the answer (days, for the reference config) is worth having up front.
    """
    import jax
    import jax.numpy as jnp

    agent, t = trainer.agent, trainer.config.train
    cfg = agent.cfg
    key = jax.random.PRNGKey(0)
    # A zero batch of the buffer's own sample shapes (the buffer is still empty).
    shapes = jax.eval_shape(trainer.buffer.sample, state.buffer, key)
    batch = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)
    if cfg.mpc:
        act, act_args = jax.jit(agent.plan), (state.agent, state.planner, state.env.obs,
                                              state.env.first, key)  # fmt: skip
    else:
        act, act_args = jax.jit(agent.act_policy), (state.agent, state.env.obs, key)

    def seconds(fn, args) -> float:
        jax.block_until_ready(fn(*args))  # compile and warm up
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        return time.perf_counter() - t0

    t_act = seconds(act, act_args)
    t_update = seconds(jax.jit(agent.update), (state.agent, batch, key))
    done, planning = (int(x) for x in jax.device_get((state.env_steps, state.planning)))
    remaining = max(t.steps - done, 0)
    cost = prog.run_cost_seconds(
        remaining,
        seed_steps_left=0 if planning else max(trainer.seed_steps - done, 0),
        num_envs=t.num_envs,
        utd=t.utd,
        pretrain_updates_left=0 if planning else trainer.pretrain_updates,
        act_seconds=t_act,
        update_seconds=t_update,
    )
    what = "plan" if cfg.mpc else "policy"
    return (
        f"CPU only: about {prog.format_duration(cost)} of agent compute for the {remaining:,} "
        f"steps left (one {what} call for {t.num_envs} env(s) {t_act:.2f} s, one update "
        f"{t_update:.2f} s, measured now); use --preset smoke or a GPU"
    )


def _check_resume_step(ckpt: Checkpointer, step: int | None) -> None:
    later = [s for s in ckpt.steps() if step is not None and s > step]
    if later:
        raise UsageError(
            f"--resume-step {step}: later checkpoints {later} exist and would mix with the new "
            "ones; move them out of checkpoints/ first (nothing was changed)"
        )


def train(args: TrainArgs) -> int:
    """The `train` command: validate, prepare the run dir, init or restore, run the loop."""
    import jax

    from sirl_jax.buffer_memory import check_buffer_fits
    from sirl_jax.compile_cache import enable_compilation_cache

    config, resuming = args.config, args.resume is not None
    if resuming:
        run_dir = Path(args.resume)
    else:
        run_dir = Path(args.run_dir or runlog.default_run_dir(config.train.task, config.train.seed))
        runlog.check_new_run_dir(run_dir)
    spec, env = load_task(config.train.task)
    try:
        config.validate_for_task(spec.episode_length, spec.success_bar)
    except ValueError as e:
        raise UsageError(str(e)) from e
    if args.wandb:
        try:
            import wandb
        except ImportError as e:
            raise UsageError("--wandb needs the wandb package: pip install wandb") from e
    enable_compilation_cache()
    from sirl_jax.train import make_train

    try:
        trainer = make_train(config, env)
    except ValueError as e:  # static checks of the components (buffer size, shapes)
        raise UsageError(str(e)) from e
    key = jax.random.PRNGKey(config.train.seed)
    nbytes = _tree_nbytes(jax.eval_shape(trainer.init, key).buffer)
    buffer = getattr(trainer, "buffer", None)
    line = buffer.describe() if hasattr(buffer, "describe") else f"buffer: {nbytes / 1e9:.3f} GB"
    agent = getattr(trainer, "agent", None)  # like `buffer`: a stand-in trainer may lack one
    print(runlog.describe_run(config, spec, line, run_dir, getattr(agent, "iterations", None)))
    on_cpu = jax.default_backend() == "cpu"
    cpu_warning = agent is not None and on_cpu and config.agent.model_size != "tiny"
    if cpu_warning:
        print(f"CPU only: a {config.agent.model_size} model is GPU-sized; timing one plan and "
              "one update to estimate the cost...", flush=True)  # fmt: skip
    check_buffer_fits(nbytes)
    run_dir.mkdir(parents=True, exist_ok=True)
    ckpt = Checkpointer(run_dir / "checkpoints", max_to_keep=args.keep)
    try:
        saved = None
        try:  # restore before writing anything, so a bad checkpoint changes nothing
            if resuming:
                _check_resume_step(ckpt, args.resume_step)
                state, saved = restore_state(ckpt, trainer.init, key, args.resume_step)
                print(f"resumed from env step {saved:,}")
            else:
                state = commit(jax.jit(trainer.init)(key))
        except jax.errors.JaxRuntimeError as e:
            if "RESOURCE_EXHAUSTED" in str(e):
                raise _oom_failure(config, e, "while allocating the train state") from e
            raise
        runlog.write_json(run_dir / "config.json", runlog.config_to_dict(config))
        runlog.record_versions(run_dir)
        wandb_run = None
        if args.wandb:
            wandb_run = wandb.init(project=args.wandb_project, name=run_dir.name,
                                   dir=str(run_dir), config=runlog.config_to_dict(config),
                                   id=run_dir.name, resume="allow")  # fmt: skip
        log = runlog.RunLog(run_dir, tensorboard=args.tensorboard, wandb_run=wandb_run)
        try:
            if saved is not None:
                log.drop_after(saved)
            initial = int(jax.device_get(state.env_steps))
            if cpu_warning:
                print(_timed_cost_line(trainer, state), flush=True)
            bar = prog.Progress(config.train.steps, initial, enabled=args.progress)
            return _loop(_Run(config, args, trainer, ckpt, log, bar, saved), state)
        finally:
            log.close()
    finally:
        ckpt.close()


def evaluate(args: EvalArgs) -> int:
    """The `eval` command: restore a run's checkpoint, evaluate, print one JSON line."""
    import jax

    run_dir = Path(args.run)
    config = runlog.load_config(run_dir, Config)
    if args.episodes is not None:
        try:
            train_cfg = dataclasses.replace(config.train, eval_episodes=args.episodes)
        except ValueError as e:
            raise UsageError(str(e)) from e
        config = dataclasses.replace(config, train=train_cfg)
    if not (run_dir / "checkpoints").is_dir():
        raise UsageError(f"{run_dir} has no checkpoints/")
    spec, env = load_task(config.train.task)
    from sirl_jax.train import make_train

    trainer = make_train(config, env)
    ckpt = Checkpointer(run_dir / "checkpoints")
    try:
        state, step = restore_state(ckpt, trainer.init, jax.random.PRNGKey(config.train.seed),
                                         args.step)  # fmt: skip
    finally:
        ckpt.close()
    out = jax.device_get(jax.jit(trainer.evaluate)(state, _eval_key(config.train.seed, step)))
    print(json.dumps({"task": spec.id, "env_steps": step, **prog.host_scalars(out)}))
    return EXIT_OK


# ---------------------------------------------------------------- commands


def tasks() -> int:
    """The `tasks` command: one line per registered task."""
    import importlib
    import importlib.util

    from sirl_jax.envs import TASKS, classic  # noqa: F401  (classic registers `pendulum`)

    if importlib.util.find_spec("sirl_jax.envs.tasks") is not None:
        importlib.import_module("sirl_jax.envs.tasks")

    aliases: dict[str, list[str]] = {}
    for alias, target in TASKS.aliases().items():
        aliases.setdefault(target, []).append(alias)
    print(f"{'task':<26} {'aliases':<18} {'T':>5} {'success':>8}  description")
    for name in sorted(TASKS):
        spec = TASKS[name]
        bar = "-" if spec.success_bar is None else f"{spec.success_bar:g}"
        alias = ",".join(sorted(aliases.get(name, []))) or "-"
        print(f"{name:<26} {alias:<18} {spec.episode_length:>5} {bar:>8}  {spec.description}")
    print("also: --task dmc:<EnvName> for a MuJoCo Playground env (needs the playground extra)")
    return EXIT_OK


USAGE = """usage: python -m sirl_jax {train,tasks,eval} [flags]

  train  python -m sirl_jax train --task hurdle [--seed 1 --steps 1000000 --num-envs 4 ...]
         --preset smoke: a CPU-sized run; --resume RUN_DIR: continue; --help: every flag
  tasks  list the registered tasks and their aliases
  eval   python -m sirl_jax eval --run RUN_DIR [--step N]: evaluate a checkpoint
"""


def _dispatch(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE, end="")
        return EXIT_OK if argv else EXIT_USAGE
    command, rest = argv[0], argv[1:]
    if command == "train":
        return train(parse_train_args(rest))
    if command == "tasks":
        return tasks()
    if command == "eval":
        return evaluate(tyro.cli(EvalArgs, args=rest, prog="python -m sirl_jax eval"))
    raise UsageError(f"unknown command {command!r}; valid commands: train, tasks, eval")


def main(argv: list[str] | None = None) -> int:
    """Runs the CLI in-process; returns the exit code (0, 1 failure, 2 bad input, 130 abort)."""
    from sirl_jax.buffer_memory import BufferTooLargeError

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

    After a second Ctrl-C the process leaves at once (`os._exit`): a normal interpreter exit
    would wait for the XLA computation still running the interrupted chunk (on CPU, a chunk
    with the pretraining updates takes half an hour). Checkpoints are written to a temporary
    directory and renamed when complete, so nothing saved is lost by not waiting.
    """
    code = main()
    if code == EXIT_ABORTED:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    raise SystemExit(code)


__all__ = ["RESUME_MUTABLE", "EvalArgs", "TrainArgs", "TrainingFailure", "UsageError", "main",
           "parse_train_args", "run"]  # fmt: skip
