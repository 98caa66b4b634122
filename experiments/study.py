"""The one study driver: an arm of a study spec (`experiments.studies.specs`) as a sweep.

    .venv/bin/python -m experiments.study --list
    .venv/bin/python -m experiments.study sit_simple_solved --arm beta1            # 3 seeds
    .venv/bin/python -m experiments.study sit_simple_solved --arm beta1 --seed 0   # seed 0 alone
    .venv/bin/python -m experiments.study sit_simple --baseline zero --episodes 64
    .venv/bin/python -m experiments.study paper_table_cpu --task walk --arm TDMPBC

An arm trains the study's seeds as one program (`sirl_jax.run.sweep_run`), or with --seed I
seed I alone, with the key it has among the study's seeds: RESULTS/<study>/<arm>/ (or
.../<arm>/seed<I>/) is a sweep directory whose runs (`seed=I/`) are run directories like any
other: `eval`, `render`, `export`, `report` and `plot` take them. Every run evaluates before
training and every `train.eval_every` steps; its eval.csv carries `time/wall_s` and
`time/train_cpu_s` (training's process CPU, evaluations excluded) across resumes. Run the same
command again and it resumes from the newest checkpoint; a finished arm returns at once.
`--until N` stops (saved) at N env steps per seed, e.g. to check a committed result's start.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import tyro

from experiments.studies.specs import STUDIES, Study, override
from sirl_jax.config import Config


@dataclasses.dataclass(frozen=True)
class Args:
    study: tyro.conf.Positional[str] = ""
    """A name of `experiments.studies.specs.STUDIES` (--list shows them)."""
    arm: str | None = None
    """Train (or resume) this arm."""
    seed: int | None = None
    """Only this seed index of the study's seeds (one seed per process)."""
    task: str | None = None
    """The task (the study's own by default; the paper's ablations take a short name)."""
    steps: int | None = None
    """Env steps per seed (the study's by default; the replay is sized to them)."""
    until: int | None = None
    """Stop at this many env steps per seed (saved; run again to go on)."""
    baseline: str | None = None
    """random or zero: that policy's return on the study's env, as RESULTS/<study>/<b>.json."""
    episodes: int = 64
    results: str = "results"
    list: bool = False


def study_of(name: str) -> Study:
    if name not in STUDIES:
        raise SystemExit(f"error: study {name!r} is unknown; allowed: {', '.join(STUDIES)}")
    return STUDIES[name]


def arm_config(study: Study, arm: str, task: str | None = None,
               steps: int | None = None) -> Config:  # fmt: skip
    """The config an arm of `study` trains (its task and steps given or the study's)."""
    if arm not in study.arms:
        raise SystemExit(f"error: --arm {arm!r} is unknown; allowed: {', '.join(study.arms)}")
    cfg = override(study.config(task or study.task), study.arms[arm])
    if steps is not None:
        cfg = override(cfg, {"train.steps": steps, "train.buffer_size": steps})
    return cfg


def run_arm(study: Study, config: Config, out: Path, seed: int | None = None,
            until: int | None = None) -> Path:  # fmt: skip
    """Trains (or resumes) the study's seeds of `config`, or seed `seed` alone, as one sweep
    under `out` (or `out/seed<I>`); returns the sweep directory."""
    from sirl_jax.run.compile_cache import enable_compilation_cache
    from sirl_jax.run.config_rules import check_resume
    from sirl_jax.run.runlog import load_config
    from sirl_jax.run.sweep_run import SWEEP_FILE, sweep_run
    from sirl_jax.sweep import Sweep

    if seed is not None and not 0 <= seed < study.seeds:
        raise SystemExit(f"error: --seed {seed} is invalid; allowed: 0..{study.seeds - 1}")
    sweep = Sweep(seeds=study.seeds if seed is None else 1, first_seed=seed or 0,
                  split=study.seeds)  # fmt: skip
    run_dir = out if seed is None else out / f"seed{seed}"
    resuming = (run_dir / SWEEP_FILE).is_file()
    if resuming:
        try:  # the sweep's base config, read as any saved config is (`runlog.load_config`)
            check_resume(load_config(run_dir, sweep_ok=True), config)
        except ValueError as e:
            raise SystemExit(f"error: cannot resume {run_dir}: {e}") from None
    enable_compilation_cache()
    sweep_run(config, sweep, run_dir, resuming=resuming, keep=2, tensorboard=False,
              eval_at_start=True, until=until, budget_cpu_s=study.budget_cpu_s)  # fmt: skip
    return run_dir


def baseline(study: Study, task: str | None, action: str, episodes: int, out: Path) -> dict:
    """The uniform random or zero action's mean and std return over `episodes` on the env of
    the study's first arm (every episode from its own reset, one jitted rollout)."""
    import jax

    from sirl_jax.envs import load
    from sirl_jax.evaluate import make_random_evaluate

    if action not in ("random", "zero"):
        raise SystemExit(f"error: --baseline {action!r} is invalid; allowed: random, zero")
    t = arm_config(study, next(iter(study.arms)), task).train
    evaluate = make_random_evaluate(load(t.task, **t.env_options)[1], episodes,
                                    "uniform" if action == "random" else "zero")  # fmt: skip
    m = jax.device_get(jax.jit(evaluate)(jax.random.PRNGKey(0)))
    p = f"eval/{action}"
    result = {"task": t.task, "policy": "uniform" if action == "random" else action,
              "episodes": episodes, "env_options": t.env_options,
              "mean": float(m[f"{p}_return"]), "std": float(m[f"{p}_return_std"]),
              "mean_length": float(m[f"{p}_length"]), "blowups": int(m[f"{p}_blowups"])}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"{action} action on {t.task}: {result['mean']:.2f} +- {result['std']:.2f} over "
          f"{episodes} episodes (mean length {result['mean_length']:.1f}) -> {out}")
    return result


def main(args: Args) -> None:
    if args.list or not args.study:
        for name, s in STUDIES.items():
            print(f"{name}: {s.doc}; arms {', '.join(s.arms)}; {s.seeds} seed(s)"
                  + (f"; report: python -m {s.report}" if s.report else ""))
        return
    study = study_of(args.study)
    root = Path(args.results) / args.study
    if args.baseline:
        baseline(study, args.task, args.baseline, args.episodes, root / f"{args.baseline}.json")
    if args.arm is not None:
        config = arm_config(study, args.arm, args.task, args.steps)
        task = args.task or (study.task if study.per_task else None)
        out = root / (args.arm if task is None else f"{task}/{args.arm}")
        run_arm(study, config, out, args.seed, args.until)


if __name__ == "__main__":
    main(tyro.cli(Args))
