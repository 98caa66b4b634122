"""`train --seeds N --sweep FIELD=V1,V2`: a sweep's runs trained as one vmapped program, each
in a run directory of its own.

    RUN_DIR/sweep.json     the axes, the seeds and every run's name, in the program's order
    RUN_DIR/<name>/        a run directory like any other (e.g. beta=0_seed=1): config.json
                           with the run's own values, checkpoints/ of its slice of the state,
                           metrics.csv, eval.csv, tb/

`eval`, `render`, `export`, `report` and `plot` take RUN_DIR/<name> as they take a run trained
alone; `plot RUN_DIR/*` draws each point of the grid as mean ± std over its seeds. A run whose
chunk goes non-finite is stopped alone (its last checkpoint kept, a line says so) while the
others go on; the per-env reset already survives physics blow-ups within a run. Resume takes
the newest checkpoint every run has, so a kill between two runs' saves loses at most one
checkpoint interval of any run.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp

from sirl_jax.config import Config, config_to_dict
from sirl_jax.run import progress as prog
from sirl_jax.run import runlog
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.errors import TrainingFailure, UsageError
from sirl_jax.run.host_memory import trim_host_heap
from sirl_jax.run.runner import build, eval_key
from sirl_jax.run.states import commit, restore_state, save_state
from sirl_jax.sweep import Sweep

SWEEP_FILE = "sweep.json"


def load_sweep(run_dir: Path) -> Sweep:
    """The sweep a sweep directory was trained with (its sweep.json)."""
    raw = json.loads((run_dir / SWEEP_FILE).read_text())
    return Sweep(int(raw["seeds"]), tuple((f, tuple(vs)) for f, vs in raw["axes"].items()),
                 int(raw.get("first_seed", 0)), int(raw.get("split", 0)))  # fmt: skip


class Clock:
    """The program's seconds, carried across resumes in each checkpoint's meta: `time/wall_s`
    since the sweep began, evaluations and checkpoints included (what a user waits); and
    `time/train_cpu_s`, the process CPU time of all threads outside evaluations (the unit in
    which configs that share a machine with other work compare fairly), which the program's
    runs share."""

    FIELDS = ("time/wall_s", "time/train_cpu_s")

    def __init__(self, wall_s: float = 0.0, train_cpu_s: float = 0.0):
        self.wall0, self.cpu0 = wall_s, train_cpu_s
        self.t0, self.c0, self.set_aside = time.perf_counter(), time.process_time(), 0.0

    def start(self) -> None:
        self.t0, self.c0, self.set_aside = time.perf_counter(), time.process_time(), 0.0

    def train_cpu(self) -> float:
        return self.cpu0 + time.process_time() - self.c0 - self.set_aside

    @contextlib.contextmanager
    def aside(self):
        """CPU time spent inside is not training's."""
        c = time.process_time()
        try:
            yield
        finally:
            self.set_aside += time.process_time() - c

    def read(self) -> dict[str, float]:
        wall = self.wall0 + time.perf_counter() - self.t0
        return dict(zip(self.FIELDS, (round(wall, 1), round(self.train_cpu(), 1)), strict=True))


def _slice(tree, r: int):
    return jax.tree.map(lambda x: x[r], tree)


def _common_step(ckpts: list[Checkpointer], names: list[str]) -> int:
    """The newest checkpoint step every run has."""
    steps = [set(c.steps()) for c in ckpts]
    missing = [n for n, s in zip(names, steps, strict=True) if not s]
    if missing:
        raise UsageError(f"--resume: runs {', '.join(missing)} have no checkpoint; nothing to "
                         "resume (nothing was changed)")  # fmt: skip
    common = set.intersection(*steps)
    if not common:
        raise UsageError("--resume: the runs have no checkpoint step in common (nothing was "
                         "changed)")  # fmt: skip
    return max(common)


class SweepRun:
    """The runs' logs, checkpoints and best evaluations, and the vmapped loop over them."""

    def __init__(self, config: Config, sweep: Sweep, run_dir: Path, keep: int,
                 tensorboard: bool, show_progress: bool):  # fmt: skip
        self.config, self.sweep, self.run_dir = config, sweep, run_dir
        self.configs, self.names = sweep.configs(config), sweep.names()
        self.dirs = [run_dir / n for n in self.names]
        self.ckpts = [Checkpointer(d / "checkpoints", max_to_keep=keep) for d in self.dirs]
        self.tensorboard, self.show_progress = tensorboard, show_progress
        self.keys = sweep.keys(config)
        self.best = [(-math.inf, 0)] * len(sweep)
        self.failed: dict[int, str] = {}
        self.clock = Clock()

    def restore(self, train) -> tuple[object, int]:
        for c in self.ckpts:
            for path in c.remove_partial_writes():
                print(f"note: removed {path}, an unfinished checkpoint write")
        step = _common_step(self.ckpts, self.names)
        states = [restore_state(c, train.init, jax.random.PRNGKey(cfg.train.seed), step)[0]
                  for c, cfg in zip(self.ckpts, self.configs, strict=True)]  # fmt: skip
        meta = self.ckpts[0].meta(step)
        self.clock = Clock(*(float(meta.get(k, 0.0)) for k in Clock.FIELDS))
        for r, c in enumerate(self.ckpts):
            best = c.best()
            self.best[r] = (best["value"], best["step"]) if best else (-math.inf, 0)
        return commit(jax.tree.map(lambda *xs: jnp.stack(xs), *states)), step

    def save(self, state, r: int) -> int:
        return save_state(self.ckpts[r], _slice(state, r), self.config.train.save_buffer,
                          self.clock.read())  # fmt: skip

    def evaluate(self, eval_fn, state, env_steps: int, logs, bar) -> None:
        with self.clock.aside():
            keys = jnp.stack([eval_key(k, env_steps) for k in self.keys])
            ev = jax.device_get(eval_fn(state, keys))
        clock = self.clock.read()
        which = "planner" if self.config.agent.plans else "policy"
        shown = []
        for r, log in enumerate(logs):
            if r in self.failed:
                continue
            metrics = prog.host_scalars(_slice(ev, r))
            log.log("eval", env_steps, {**metrics, **clock})
            value = metrics[f"eval/{which}_return"]
            shown.append(f"{self.names[r]} {value:.4g}")
            if value > self.best[r][0]:  # kept past --keep: eval/render/export --best
                self.best[r] = (value, env_steps)
                self.save(state, r)
                self.ckpts[r].mark_best(env_steps, value, f"eval/{which}_return")
        bar.write(f"eval @ {env_steps:,} ({which} return): " + ", ".join(shown))

    def cost(self, seconds: float, steps: int, left: int) -> str:
        """The cost line: one chunk's seconds for all runs and per run, and the time left."""
        r = len(self.names)
        return (f"cost: {seconds:.3g} s per chunk of {steps:,} env steps for {r} runs, "
                f"{seconds / r:.3g} s per run ({steps * r / seconds:.4g} env steps/s over the "
                f"runs); about {prog.format_duration(seconds * left / steps)} to go "
                "(evaluations and checkpoints not counted)")  # fmt: skip

    def loop(self, train, state, logs, eval_at_start: bool = False, until: int | None = None,
             budget_cpu_s: float | None = None) -> None:  # fmt: skip
        """Trains to `train.steps`, or to `until` env steps, or until the training chunks have
        used `budget_cpu_s` of process CPU (evaluated and saved then); `eval_at_start`: an
        evaluation before the first chunk of a fresh sweep (the untrained networks)."""
        t, names = self.config.train, self.names
        last = min(t.steps, until or t.steps)
        step_fn = jax.jit(jax.vmap(train.step), donate_argnums=0)
        eval_fn = jax.jit(jax.vmap(train.evaluate))
        env_steps = int(jax.device_get(state.env_steps)[0])
        means = [prog.MetricMean() for _ in names]
        bar = prog.Progress(t.steps, env_steps, enabled=self.show_progress)
        self.clock.start()
        with prog.StopOnSigint() as stop, contextlib.closing(bar):
            if eval_at_start and env_steps == 0:
                self.evaluate(eval_fn, state, 0, logs, bar)
            chunks, costed = 0, False
            over = budget_cpu_s is not None and self.clock.train_cpu() >= budget_cpu_s
            while env_steps < last and not stop.requested and not over:
                before, t0 = env_steps, time.perf_counter()
                state, metrics = step_fn(state)
                metrics = jax.device_get(metrics)
                env_steps, chunks = int(metrics["env_steps"][0]), chunks + 1
                if chunks > 1 and not costed and metrics["train/num_updates"].min() > 0:
                    costed = True  # the first chunk with updates, past the compiling one
                    bar.write(self.cost(time.perf_counter() - t0, env_steps - before,
                                        t.steps - env_steps))  # fmt: skip
                alive = [r for r in range(len(names)) if r not in self.failed]
                for r in alive:
                    m = prog.host_scalars(_slice(metrics, r))
                    bad = prog.failures(m, env_steps - before, t.max_blowup_rate)
                    if bad:
                        self.failed[r] = (f"run {names[r]} failed in the chunk ending at env "
                                          f"step {env_steps:,}: {'; '.join(bad)}; its last "
                                          f"checkpoint is kept; the other runs go on")  # fmt: skip
                        bar.write(f"warning: {self.failed[r]}")
                        logs[r].log("metrics", env_steps, m)
                        continue
                    means[r].add(m)
                    if prog.crossed(before, env_steps, t.log_every) or env_steps >= t.steps:
                        logs[r].log("metrics", env_steps, {**means[r].pop(), **self.clock.read()})
                alive = [r for r in alive if r not in self.failed]
                if not alive:
                    raise TrainingFailure(f"every run of the sweep failed: {self.failed}")
                head = prog.host_scalars(_slice(metrics, alive[0]))
                bar.update(env_steps, int(head["updates"]) * len(alive), head)
                over = budget_cpu_s is not None and self.clock.train_cpu() >= budget_cpu_s
                evaluated = prog.crossed(before, env_steps, t.eval_every) or over
                if evaluated:
                    self.evaluate(eval_fn, state, env_steps, logs, bar)
                saved = prog.crossed(before, env_steps, t.checkpoint_interval) or over
                for r in alive if saved else ():
                    self.save(state, r)
                if evaluated or saved:
                    trim_host_heap()
        for r in range(len(names)):
            if r not in self.failed:
                if stop.requested and means[r].pending():
                    logs[r].log("metrics", env_steps, means[r].pop())
                self.save(state, r)
        how = ("done" if env_steps >= t.steps else "stopped at the CPU budget" if over
               else f"stopped (until {until:,})" if env_steps >= last
               else "stopped (Ctrl-C/SIGTERM)")  # fmt: skip
        print(f"sweep {how} at env step {env_steps:,} per run: {len(names) - len(self.failed)} "
              f"of {len(names)} runs saved in {self.run_dir}/<run>/checkpoints"
              + (f"; continue with: python -m sirl_jax train --resume {self.run_dir}"
                 if env_steps < t.steps else ""))  # fmt: skip
        for message in self.failed.values():
            print(f"warning: {message}")


def sweep_run(config: Config, sweep: Sweep, run_dir: Path | None, *, resuming: bool = False,
              keep: int = 3, show_progress: bool = True,
              tensorboard: bool = True, **stop) -> None:  # fmt: skip
    """Trains (or resumes) every run of `sweep` over `config` in one program under `run_dir`
    (None: the default name for a new sweep); `stop`: `SweepRun.loop`'s eval_at_start, until
    and budget_cpu_s. One pass through the shell: build the program (`runner.build`), then
    the run directory, its files and logs (`runlog`), then the loop."""
    from sirl_jax.run.buffer_memory import check_buffer_fits

    spec, train = build(config)
    if not resuming:
        run_dir = runlog.new_run_dir(run_dir, config.train.task, config.train.seed)
    run = SweepRun(config, sweep, run_dir, keep, tensorboard, show_progress)
    axes = ", ".join(f"{f}={','.join(f'{v:g}' for v in vs)}" for f, vs in sweep.axes)
    print(runlog.describe_run(config, spec, train.buffer.describe(), run_dir,
                              train.agent.iterations, None))  # fmt: skip
    print(f"sweep: {len(sweep)} runs in one program ({sweep.seeds} seeds"
          + (f" x {axes}" if axes else "") + f"): {', '.join(run.names)}")  # fmt: skip
    check_buffer_fits(train.buffer.nbytes * len(sweep))
    try:
        if resuming:
            state, step = run.restore(train)
            print(f"resumed every run from env step {step:,}")
        else:
            state, step = commit(jax.jit(sweep.init(train, config))()), None
        run_dir.mkdir(parents=True, exist_ok=True)
        runlog.write_json(run_dir / "config.json", config_to_dict(config))  # what --resume reads
        runlog.write_json(run_dir / SWEEP_FILE, {
            "seeds": sweep.seeds, "axes": {f: list(vs) for f, vs in sweep.axes},
            "first_seed": sweep.first_seed, "split": sweep.split, "runs": run.names})  # fmt: skip
        logs = []
        for d, cfg in zip(run.dirs, run.configs, strict=True):
            runlog.write_json(d / "config.json", config_to_dict(cfg))
            runlog.record_versions(d)
            logs.append(runlog.RunLog(d, tensorboard=tensorboard))
            if step is not None:
                logs[-1].drop_after(step)
        try:
            run.loop(train, state, logs, **stop)
        finally:
            for log in logs:
                log.close()
    finally:
        for c in run.ckpts:
            c.close()


def is_sweep(args) -> bool:
    """`train` args that ask for a sweep: --seeds/--sweep, or --resume of a sweep directory."""
    resumed = args.resume is not None and (Path(args.resume) / SWEEP_FILE).is_file()
    return args.seeds != 1 or bool(args.sweep) or resumed


def sweep_command(args) -> None:
    """`train` with --seeds/--sweep, or --resume of a sweep directory (`cli.train`)."""
    from sirl_jax.run.compile_cache import enable_compilation_cache
    from sirl_jax.sweep import SweepError

    unsupported = [(args.devices != 1, f"--devices {args.devices}"), (args.wandb, "--wandb"),
                   (args.resume_step is not None, "--resume-step"),
                   (args.config.train.video_every > 0, "--train.video-every")]  # fmt: skip
    for given, flag in unsupported:
        if given:
            raise UsageError(f"{flag} cannot be combined with a sweep (--seeds/--sweep); "
                             "a sweep runs on one device and resumes from its newest "
                             "checkpoint")  # fmt: skip
    resuming = args.resume is not None
    config = args.config
    given = args.resume if resuming else args.run_dir
    run_dir = Path(given) if given else None  # a new one is named and checked by `sweep_run`
    try:
        if resuming:
            if args.sweep or args.seeds != 1:
                raise UsageError("--seeds/--sweep cannot be combined with --resume (the saved "
                                 f"sweep, {run_dir / SWEEP_FILE}, is used)")  # fmt: skip
            assert run_dir is not None
            sweep = load_sweep(run_dir)
        else:
            sweep = Sweep.parse(args.seeds, args.sweep)
        sweep.configs(config)  # a value the config refuses, before any work
    except SweepError as e:
        raise UsageError(str(e)) from e
    enable_compilation_cache()
    sweep_run(config, sweep, run_dir, resuming=resuming, keep=args.keep,
              show_progress=args.progress, tensorboard=args.tensorboard)  # fmt: skip
