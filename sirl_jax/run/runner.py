"""The run loop behind `train` and `eval`: chunks, evaluation and checkpoint cadence, failures.

`train_run` validates, prepares the run directory, initialises or restores the train state and
calls the jitted `Train.step` until `train.steps`, a Ctrl-C or a failure. Everything here runs
on the host at chunk boundaries; only `Train.step`, `Train.evaluate` and the state copy run
under `jit`. No error path deletes or overwrites anything already saved.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

import jax

from sirl_jax.config import Config, config_to_dict
from sirl_jax.envs import load
from sirl_jax.envs import spec as registered_spec
from sirl_jax.run import progress as prog
from sirl_jax.run import runlog
from sirl_jax.run.checkpoint import Checkpointer, CheckpointWriteError
from sirl_jax.run.cost_probe import cost_line, cpu_hint
from sirl_jax.run.errors import TrainingFailure, UsageError
from sirl_jax.run.host_memory import trim_host_heap
from sirl_jax.run.states import commit, copy_state, restore_state, save_state
from sirl_jax.sharding import ENVS, batch_constraint, env_shardings, make_mesh, place, sharded_step
from sirl_jax.train import Train, make_train

_EVAL_STREAM = 0x6576616C  # folded into the seed so evaluation keys never meet training keys


# ---------------------------------------------------------------- building blocks


def load_task(task: str, build_env: bool = True, **options):
    """(TaskSpec, Env) of a task name, with bad names and missing extras as UsageError;
    `build_env=False`: the registered spec alone, (spec, None), nothing compiled. `options`:
    `sirl_jax.envs.load`'s (`TrainConfig.env_options`: hb_compat, contact_set, hand_floor,
    contact_budget; sirl_jax/hb_compat.py)."""
    try:
        if build_env:
            return load(task, **options)
        return (registered_spec(task), None)
    except KeyError as e:
        raise UsageError(e.args[0]) from e
    except ImportError as e:
        raise UsageError(f"--task {task} needs an optional package: {e}") from e


def build(config: Config) -> tuple[Any, Train]:
    """(spec, Train) of a config; a config that does not fit its task, or a physics impl that
    cannot run here, is a UsageError. Warp's contact pool is sized for the larger of the train
    and the eval envs (one seed)."""
    from sirl_jax.envs.loading import with_physics
    from sirl_jax.envs.physics import Physics

    t = config.train
    spec, env = load_task(t.task, **t.env_options)
    try:
        env = with_physics(env, Physics(t.impl, num_worlds=max(t.num_envs, t.eval_episodes)))
    except (ImportError, RuntimeError, ValueError) as e:
        raise UsageError(f"--train.impl {t.impl}: {e}") from e
    try:
        return spec, make_train(config, env)
    except ValueError as e:
        raise UsageError(str(e)) from e


def shard_envs(train: Train, devices: int, key: jax.Array) -> tuple[Train, Any]:
    """`train` rebuilt with its batch split over `devices` local devices, and the state's
    shardings (envs and buffer split, the rest replicated: `sirl_jax.sharding`, layout envs)."""
    t = train.config
    try:
        mesh = make_mesh(devices, ENVS)
        shardings = env_shardings(jax.eval_shape(train.init, key), mesh, t.train.num_envs,
                                  t.agent.sample_size)  # fmt: skip
    except ValueError as e:
        raise UsageError(str(e)) from e
    return make_train(t, train.env, constrain_batch=batch_constraint(mesh)), shardings


def eval_key(seed: int | jax.Array, env_steps: int) -> jax.Array:
    """The evaluation key of a run at `env_steps` (the same for `train` and `eval`); `seed`:
    the run's seed, or its key where that is not PRNGKey(seed) (`Sweep.split`)."""
    key = jax.random.PRNGKey(seed) if isinstance(seed, int) else seed
    base = jax.random.fold_in(key, _EVAL_STREAM)
    return jax.random.fold_in(base, env_steps)


def _oom_failure(config: Config, error: Exception, where: str) -> TrainingFailure:
    t, a = config.train, config.agent
    first = str(error).strip().splitlines()[0][:200]
    return TrainingFailure(
        f"out of device memory {where} ({first}); reduce --buffer-size (now {t.buffer_size:,}), "
        f"--num-envs ({t.num_envs}), --chunk-steps ({t.chunk_steps}), --agent.batch-size "
        f"({a.batch_size}), --agent.num-samples ({a.num_samples}) or --model-size "
        f"({a.model_size}), or pass --no-guard"
    )


@contextlib.contextmanager
def _oom_as_failure(config: Config, where: str):
    try:
        yield
    except jax.errors.JaxRuntimeError as e:
        if "RESOURCE_EXHAUSTED" in str(e):
            raise _oom_failure(config, e, where) from e
        raise


# ---------------------------------------------------------------- the loop


@dataclasses.dataclass
class Run:
    """What the loop needs besides the state; `saved` is the newest checkpointed env step."""

    config: Config
    train: Train
    ckpt: Checkpointer
    log: runlog.RunLog
    bar: prog.Progress
    guard: bool = True
    saved: int | None = None
    best: tuple[float, int] = (-math.inf, 0)  # best eval return so far and its env step
    collapse: str | None = None  # the first collapse warning, repeated in the final summary
    shardings: Any = None  # the state's layout over devices (`shard_envs`); None: one device
    videos: Any = None  # `videos.TrainingVideos` with --train.video-every, else None

    def evaluate(self, eval_fn, state, env_steps: int) -> dict[str, float]:
        key = eval_key(self.config.train.seed, env_steps)
        metrics = prog.host_scalars(jax.device_get(eval_fn(state, key)))
        self.log.log("eval", env_steps, metrics)
        self.bar.write(f"eval @ {env_steps:,}: "
                       + ", ".join(f"{k} {v:.4g}" for k, v in metrics.items()))  # fmt: skip
        which = "planner" if self.config.agent.plans else "policy"
        value = metrics[f"eval/{which}_return"]
        if self.best[0] > 0 and value < 0.5 * self.best[0] and self.collapse is None:
            self.collapse = (f"warning: eval {which} return collapsed to {value:.4g} at env step "
                             f"{env_steps:,}, below half its best {self.best[0]:.4g} (env step "
                             f"{self.best[1]:,})")  # fmt: skip
            self.bar.write(self.collapse)
        if value > self.best[0]:  # kept past --keep: eval/render/export --best
            self.best = (value, env_steps)
            self.saved = self.save(state)
            self.ckpt.mark_best(env_steps, value, f"eval/{which}_return")
        return metrics

    def save(self, state) -> int:
        """Checkpoints `state`; a failed write (disk full) stops the run as a failure."""
        try:
            return save_state(self.ckpt, state, self.config.train.save_buffer)
        except CheckpointWriteError as e:
            raise TrainingFailure(f"{e}; free space and continue with: python -m sirl_jax "
                                  f"train --resume {self.log.run_dir}") from e  # fmt: skip

    def nonfinite_failure(self, backup, reached: int, bad: list[str]) -> TrainingFailure:
        where = f"the chunk ending at env step {reached:,} failed: {'; '.join(bad)}"
        if backup is not None:
            good = self.save(backup)
            return TrainingFailure(f"{where}; the last good state (env step {good:,}) is "
                                   f"saved in {self.ckpt.directory} with the earlier "
                                   "checkpoints")  # fmt: skip
        return TrainingFailure(f"{where}; the state was not saved (--no-guard); the last "
                               f"checkpoint is env step {self.saved}")  # fmt: skip

    def loop(self, state) -> None:
        """Runs chunks until train.steps, a Ctrl-C or a failure; checkpoints the final state."""
        t = self.config.train
        if self.shardings is None:
            step_fn = jax.jit(self.train.step, donate_argnums=0)
        else:
            step_fn = sharded_step(self.train.step, self.shardings)
        backup_fn = jax.jit(copy_state) if self.guard else (lambda s: None)
        eval_fn = jax.jit(self.train.evaluate)
        env_steps, updates = (int(x) for x in jax.device_get((state.env_steps, state.updates)))
        mean, first = prog.MetricMean(), True
        with prog.StopOnSigint() as stop, contextlib.closing(self.bar):
            while env_steps < t.steps and not stop.requested:
                before = env_steps
                with _oom_as_failure(self.config, f"at env step {before:,} (last checkpoint: "
                                                  f"{self.saved})"):  # fmt: skip
                    backup = backup_fn(state)
                    state, metrics = step_fn(state)
                    metrics = prog.host_scalars(jax.device_get(metrics))
                env_steps, updates = int(metrics["env_steps"]), int(metrics["updates"])
                bad = prog.failures(metrics, env_steps - before, t.max_blowup_rate)
                if bad:
                    self.log.log("metrics", env_steps, metrics)
                    raise self.nonfinite_failure(backup, env_steps, bad)
                self.bar.update(env_steps, updates, metrics)
                mean.add(metrics)
                if prog.crossed(before, env_steps, t.log_every) or env_steps >= t.steps:
                    self.log.log("metrics", env_steps, mean.pop())
                evaluated = prog.crossed(before, env_steps, t.eval_every)
                if evaluated:
                    self.evaluate(eval_fn, state, env_steps)
                if self.videos is not None:
                    self.videos.maybe(state, before, env_steps)
                saved = prog.crossed(before, env_steps, t.checkpoint_interval)
                if saved:
                    self.saved = self.save(state)
                if evaluated or saved or first:  # what a compile, an eval or a save freed
                    trim_host_heap()
                first = False
        if stop.requested and env_steps < t.steps and mean.pending():
            self.log.log("metrics", env_steps, mean.pop())
        self.saved = self.save(state)
        if self.collapse is not None:
            print(self.collapse)
        how = "stopped (Ctrl-C/SIGTERM)" if env_steps < t.steps else "done"
        print(f"{how} at env step {env_steps:,}; checkpoint saved in {self.ckpt.directory}"
              + (f"; continue with: python -m sirl_jax train --resume {self.log.run_dir}"
                 if env_steps < t.steps else ""))  # fmt: skip


def check_resume_step(ckpt: Checkpointer, step: int | None) -> None:
    later = [s for s in ckpt.steps() if step is not None and s > step]
    if later:
        raise UsageError(
            f"--resume-step {step}: later checkpoints {later} exist and would mix with the new "
            "ones; move them out of checkpoints/ first (nothing was changed)"
        )


def train_command(args, derived: dict, videos_factory=None) -> None:
    """`train` from parsed `cli.TrainArgs`: the run dir, the wandb extra, then `train_run`."""
    from sirl_jax.run.compile_cache import enable_compilation_cache

    config, resuming = args.config, args.resume is not None
    if resuming:
        run_dir = Path(args.resume)
    else:
        run_dir = Path(args.run_dir or runlog.default_run_dir(config.train.task, config.train.seed))
        runlog.check_new_run_dir(run_dir)
    wandb_run_factory = None
    if args.wandb:
        try:
            import wandb
        except ImportError as e:
            raise UsageError("--wandb needs the wandb package: pip install wandb") from e

        def wandb_run_factory(d: Path):
            return wandb.init(project=args.wandb_project, name=d.name, dir=str(d), id=d.name,
                              resume="allow", config=config_to_dict(config))  # fmt: skip

    enable_compilation_cache()
    train_run(config, run_dir, resume_step=args.resume_step, resuming=resuming, derived=derived,
              keep=args.keep, guard=args.guard, show_progress=args.progress,
              tensorboard=args.tensorboard, wandb_run_factory=wandb_run_factory,
              devices=args.devices, videos_factory=videos_factory)  # fmt: skip


def print_tasks() -> None:
    """One line per registered task: id, aliases, T, success bar, description."""
    from sirl_jax.envs import TASKS

    aliases: dict[str, list[str]] = {}
    for alias, target in TASKS.aliases().items():
        aliases.setdefault(target, []).append(alias)
    print(f"{'task':<26} {'aliases':<18} {'T':>5} {'success':>8}  description")
    for name in sorted(TASKS):
        spec = TASKS[name]
        bar = "-" if spec.success_bar is None else f"{spec.success_bar:g}"
        alias = ",".join(sorted(aliases.get(name, []))) or "-"
        print(f"{name:<26} {alias:<18} {spec.episode_length:>5} {bar:>8}  {spec.description}")
    print("also: --task dmc:<EnvName> / playground:<EnvName> for a MuJoCo Playground env")


def train_run(config: Config, run_dir: Path, *, resume_step: int | None = None,
              resuming: bool = False, derived: dict | None = None, keep: int = 3,
              guard: bool = True, show_progress: bool = True, tensorboard: bool = True,
              wandb_run_factory=None, devices: int = 1,
              videos_factory=None) -> None:  # fmt: skip
    """The body of `train`: build, restore or init, log the run's facts, run the loop.
    videos_factory: `videos.TrainingVideos` (the shell's), for `train.video_every`."""
    from sirl_jax.run.buffer_memory import check_buffer_fits

    spec, train = build(config)
    key = jax.random.PRNGKey(config.train.seed)
    train, shardings = shard_envs(train, devices, key) if devices != 1 else (train, None)
    print(runlog.describe_run(config, spec, train.buffer.describe(), run_dir,
                              train.agent.iterations, derived))  # fmt: skip
    on_cpu = jax.default_backend() == "cpu"
    probe_cost = config.agent.model_size != "tiny"  # on any device: the same measured estimate
    if probe_cost and on_cpu and config.agent.kind == "tdmpc2":
        print(f"CPU only: a {config.agent.model_size} model is GPU-sized; timing one plan and "
              "one update to estimate the cost...", flush=True)  # fmt: skip
    elif probe_cost and on_cpu:
        print("CPU only: timing one act and one update to estimate the cost...", flush=True)
    check_buffer_fits(train.buffer.nbytes)
    run_dir.mkdir(parents=True, exist_ok=True)
    ckpt = Checkpointer(run_dir / "checkpoints", max_to_keep=keep)
    try:
        saved = None
        with _oom_as_failure(config, "while allocating the train state"):
            # restore before writing anything, so a bad checkpoint changes nothing
            if resuming:
                check_resume_step(ckpt, resume_step)
                for path in ckpt.remove_partial_writes():
                    print(f"note: removed {path}, an unfinished checkpoint write (the run was "
                          "killed while saving)", file=sys.stderr)  # fmt: skip
                state, saved = restore_state(ckpt, train.init, key, resume_step,
                                             fall_back=resume_step is None)  # fmt: skip
                print(f"resumed from env step {saved:,}")
            else:
                state = commit(jax.jit(train.init)(key))
            if shardings is not None:
                state = place(state, shardings)
        runlog.write_json(run_dir / "config.json", config_to_dict(config))
        runlog.record_versions(run_dir)
        wandb_run = wandb_run_factory(run_dir) if wandb_run_factory else None
        log = runlog.RunLog(run_dir, tensorboard=tensorboard, wandb_run=wandb_run)
        try:
            if saved is not None:
                log.drop_after(saved)
            if probe_cost:
                hint = cpu_hint(config) if on_cpu else ""
                print(cost_line(train, state) + hint, flush=True)
            bar = prog.Progress(config.train.steps, int(jax.device_get(state.env_steps)),
                                enabled=show_progress)  # fmt: skip
            best = ckpt.best() if saved is not None else None
            best = (best["value"], best["step"]) if best else (-math.inf, 0)
            videos = None
            if config.train.video_every and videos_factory is not None:
                videos = videos_factory(config, train, run_dir, log, bar.write, eval_key)
            Run(config, train, ckpt, log, bar, guard, saved, best, shardings=shardings,
                videos=videos).loop(state)
        finally:
            log.close()
    finally:
        ckpt.close()
