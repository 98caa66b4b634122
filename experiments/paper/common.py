"""Shared by the paper's commands: scales, S seeds vmapped in one program, resumable arms.

`run_arm(config, seeds, out)` trains `seeds` seeds of one config as one vmapped program and
writes, under `out`:
  train.csv     per chunk and seed: env steps, wall-clock, training-episode return, R_max;
  eval.csv      per evaluation and seed: planner and policy-prior return (eval mode);
  checkpoints/  the vmapped train state after each evaluation (atomic, CRC-checked);
  done.json     written last, with the arm's wall-clock and env steps/s.
With several local devices and S a multiple of their number, the seeds are split over them
(`sirl_jax.sharding`, layout seeds: the same results, no communication).
Run again with the same arguments it resumes from the newest checkpoint (CSV rows past it are
dropped) or, when done.json exists, returns the recorded summary at once.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import time
from pathlib import Path

import jax
import numpy as np

from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.config import Config, TrainConfig
from sirl_jax.envs import load
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.compile_cache import enable_compilation_cache
from sirl_jax.run.config_rules import check_resume
from sirl_jax.run.host_memory import trim_host_heap
from sirl_jax.run.reference import paper_2m, paper_hours
from sirl_jax.run.runlog import CsvLog, RunDirError, load_config
from sirl_jax.run.states import commit
from sirl_jax.sharding import SEEDS, make_mesh, place, seed_shardings, sharded_step
from sirl_jax.train import make_train

# The paper's results table (HumanoidBench h1hand, return at 2M steps, mean ± std of 3 seeds):
# task -> (success bar, (TDMPBC mean, std), (TD-MPC2 mean, std)), from the reference data file.
PAPER_TABLE = {task: (row["success_bar"], tuple(row["TDMPBC"]), tuple(row["TD-MPC2"]))
               for task, row in paper_2m().items()}  # fmt: skip
ARMS = {"TDMPBC": 1.0, "TD-MPC2": 0.0}
"""The paper's two arms by their beta: TDMPBC and plain TD-MPC2."""
# The paper's runtime table: hours for 2M steps of 3 seeds on one V100.
PAPER_HOURS = {task: (row["TDMPBC"], row["TD-MPC2"]) for task, row in paper_hours().items()}

SCALES = ("paper", "cpu")


def task_id(task: str, scale: str) -> str:
    """paper: the h1hand task (61 actuators); cpu: the hand-less h1 variant (19)."""
    return f"h1hand-{task}-v0" if scale == "paper" else f"h1-{task}-v0"


def scale_config(scale: str, task: str, beta: float = 1.0, g_source: str = "rmax",
                 steps: int | None = None) -> Config:  # fmt: skip
    """The paper's config (5M model, 512 x 8 MPPI, 1 env, 2M steps), or its CPU stand-in: the
    `cpu` preset's agent (`AgentConfig.small`: latent 64, MLP 128, 2 Qs, 64 x 2 MPPI, batch 64)
    on 4 envs, UTD 0.25."""
    if scale not in SCALES:
        raise SystemExit(f"error: --scale {scale!r} is invalid; allowed: {', '.join(SCALES)}")
    sirl = SirlConfig(beta=beta, g_source=g_source)
    if scale == "paper":
        return Config(agent=AgentConfig(entropy_form="v1", sirl=sirl),
                      train=TrainConfig(task=task_id(task, scale), steps=steps or 2_000_000))
    steps = steps or 80_000
    return Config(
        agent=AgentConfig.small(sirl=sirl),
        train=TrainConfig(task=task_id(task, scale), steps=steps, num_envs=4, chunk_steps=50,
                          utd=0.25, seed_steps=5_000, buffer_size=steps,
                          eval_every=max(steps // 4, 1), eval_episodes=4),
    )  # fmt: skip


def _finite(x: float, digits: int = 3):
    return round(float(x), digits) if math.isfinite(float(x)) else ""


def arm_env(config: Config):
    """The env `config` trains on: its task built with its env options (`TrainConfig.env_options`:
    hb_compat, contact_set, hand_floor, contact_budget), as the CLI builds it."""
    return load(config.train.task, **config.train.env_options)[1]


def check_resume_config(out: Path, config: Config, label: str) -> None:
    """Exits unless `config` may resume the arm trained in `out` under the CLI's rule
    (`config_rules.check_resume`: only `RESUME_MUTABLE` fields may change, the replay capacity
    may not), naming each changed field. The saved config is `out`'s config.json; one saved
    before the env options existed reads as the env it ran on (`runlog.load_config`)."""
    try:
        check_resume(load_config(out), config)
    except (RunDirError, ValueError) as e:
        raise SystemExit(f"error: {label}: cannot resume {out}: {e}") from None


def run_arm(config: Config, seeds: int, out: Path, label: str,
            max_chunks: int | None = None, budget_cpu_s: float | None = None,
            keep: int | None = 2, only: tuple[int, ...] | None = None) -> dict:  # fmt: skip
    """Trains `seeds` seeds of `config` vmapped, resumably; returns done.json's summary.

    only: train just these seed indices of the `seeds` (each with the key it has in the
    vmapped run, and its index in the CSVs' seed column), e.g. one seed per process.

    max_chunks: stop after this many chunks of this call (a timing probe); nothing is marked
    done then. budget_cpu_s: stop (evaluated, checkpointed and done) once the training chunks
    have used this much process CPU time (all threads, evaluations excluded): the unit a
    config's learning is compared in when other work shares the machine. keep: the newest
    checkpoints kept (None: every evaluation's, for a probe of consecutive checkpoints).
    """
    enable_compilation_cache()
    if (out / "done.json").exists():
        return json.loads((out / "done.json").read_text())
    tc = config.train
    ckpt = Checkpointer(out / "checkpoints", max_to_keep=keep)
    if ckpt.latest_step() is not None:
        check_resume_config(out, config, label)
    train = make_train(config, arm_env(config))
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(json.dumps(dataclasses.asdict(config), indent=1))
    keys = jax.random.split(jax.random.PRNGKey(0), seeds)
    ids = tuple(range(seeds)) if only is None else tuple(only)
    if not ids or min(ids) < 0 or max(ids) >= seeds or len(set(ids)) != len(ids):
        raise ValueError(f"only={only!r} is invalid; allowed: distinct seed indices in "
                         f"0..{seeds - 1}")  # fmt: skip
    keys, seeds = keys[np.asarray(ids)], len(ids)
    print(f"{label}: {tc.task}, seeds {', '.join(map(str, ids))} x {tc.num_envs} envs, beta "
          f"{config.agent.sirl.beta:g}, G {config.agent.sirl.g_source}, {tc.steps:,} steps per "
          f"seed; {train.buffer.describe()}", flush=True)  # fmt: skip
    init = jax.vmap(train.init)
    step = jax.jit(jax.vmap(train.step), donate_argnums=0)
    evaluate = jax.jit(jax.vmap(train.evaluate))
    eval_keys = jax.vmap(lambda k: jax.random.fold_in(k, 0x6576616C))(keys)
    train_csv, eval_csv = CsvLog(out / "train.csv"), CsvLog(out / "eval.csv")
    start, wall0, cpu0 = time.perf_counter(), 0.0, 0.0
    eval_cpu = 0.0  # process CPU time spent in evaluations this call, excluded from cpu_s
    if ckpt.latest_step() is not None:
        restored = ckpt.restore({"state": jax.eval_shape(init, keys)})
        state, done = commit(restored["state"]), ckpt.latest_step()
        wall0 = float(restored["meta"]["wall_s"])
        cpu0 = float(restored["meta"].get("cpu_s", 0.0))
        train_csv.drop_after(done)
        eval_csv.drop_after(done)
        print(f"{label}: resumed from env step {done:,} per seed", flush=True)
    else:  # a fresh start: rows of an earlier timing probe or a run that died go
        state, done = commit(jax.jit(init)(keys)), 0
        train_csv.drop_after(-1)
        eval_csv.drop_after(-1)

    devices = jax.local_device_count()
    if devices > 1 and seeds % devices == 0:  # layout seeds: S / D seeds per device
        shardings = seed_shardings(jax.eval_shape(init, keys), make_mesh(devices, SEEDS))
        state, step = place(state, shardings), sharded_step(jax.vmap(train.step), shardings)
        print(f"{label}: {seeds} seeds split over {devices} devices", flush=True)

    def train_cpu() -> float:
        return cpu0 + time.process_time() - cpu_start - eval_cpu

    def run_eval(state, env_steps: int, wall: float) -> None:
        nonlocal eval_cpu
        c0 = time.process_time()
        ev = jax.device_get(evaluate(state, jax.vmap(jax.random.fold_in, (0, None))(
            eval_keys, env_steps)))  # fmt: skip
        for k in ("return", "length"):  # an agent without a planner (FastTD3): empty columns
            ev.setdefault(f"eval/planner_{k}", np.full(seeds, np.nan))
        eval_csv.extend([{
            "seed": ids[s], "env_steps": env_steps, "wall_s": round(wall, 1),
            "planner_return": _finite(ev["eval/planner_return"][s]),
            "planner_length": _finite(ev["eval/planner_length"][s], 2),
            "policy_return": _finite(ev["eval/policy_return"][s]),
            "policy_length": float(ev["eval/policy_length"][s]),
            "policy_return_std": _finite(ev["eval/policy_return_std"][s]),
            "policy_success": _finite(ev["eval/policy_success"][s]),
            "r_max": _finite(ev["eval/r_max"][s]), "cpu_s": round(train_cpu(), 1),
        } for s in range(seeds)])  # fmt: skip
        eval_cpu += time.process_time() - c0
        print(f"{label}: eval @ {env_steps:,}: planner {np.round(ev['eval/planner_return'], 1)}"
              f" policy {np.round(ev['eval/policy_return'], 1)} ({wall:.0f} s)", flush=True)

    cpu_start = time.process_time()
    if done == 0 and max_chunks is None:
        run_eval(state, 0, 0.0)
    chunks, timing, stopped = 0, [], "steps"
    while done < tc.steps and (max_chunks is None or chunks < max_chunks):
        if budget_cpu_s is not None and train_cpu() >= budget_cpu_s:
            stopped = "cpu budget"
            break
        state, m = step(state)
        m = jax.device_get(m)
        blowups = m["env/blowups"] > tc.max_blowup_rate * tc.steps_per_call
        if m["nonfinite_loss"].any() or blowups.any():
            raise SystemExit(f"error: {label}: non-finite losses or too many physics blow-ups "
                             f"in the chunk after {done:,}")
        before, done, chunks = done, int(m["env_steps"][0]), chunks + 1
        wall = wall0 + time.perf_counter() - start
        if bool(np.all(m["planning"] > 0)):
            timing.append((time.perf_counter(), done))
        train_csv.extend([{
            "seed": ids[s], "env_steps": done, "wall_s": round(wall, 1),
            "episode_return": _finite(m["episode/return"][s]),
            "episode_length": _finite(m["episode/length"][s], 1),
            "r_max": _finite(m["r_max"][s]), "updates": int(m["updates"][s]),
            "cpu_s": round(train_cpu(), 1),
        } for s in range(seeds)])  # fmt: skip
        over = budget_cpu_s is not None and train_cpu() >= budget_cpu_s
        if max_chunks is None and (done // tc.eval_every > before // tc.eval_every
                                   or done >= tc.steps or over):  # fmt: skip
            run_eval(state, done, wall)
            ckpt.save(done, {"state": state}, {"wall_s": wall, "cpu_s": train_cpu()})
            trim_host_heap()  # what the evaluation and the checkpoint write freed
        elif chunks == 1:
            trim_host_heap()  # what compiling the step freed
    ckpt.close()
    rate = math.nan
    if len(timing) >= 3:  # steady chunks: the first planning one still compiles or pretrains
        (t0, s0), (t1, s1) = timing[1], timing[-1]
        rate = (s1 - s0) / (t1 - t0)
    summary = {"label": label, "task": tc.task, "seeds": seeds, "env_steps": done,
               "wall_s": round(wall0 + time.perf_counter() - start, 1),
               "env_steps_per_s_per_seed": round(rate, 2),
               "train_cpu_s": round(train_cpu(), 1), "stopped": stopped}  # fmt: skip
    if max_chunks is None:
        (out / "done.json").write_text(json.dumps(summary, indent=1))
    print(f"{label}: {summary}", flush=True)
    return summary


def final_returns(out: Path) -> np.ndarray:
    """[S] planner return at the last evaluation of an arm."""
    rows = CsvLog(out / "eval.csv").rows()
    last = max(int(r["env_steps"]) for r in rows)
    return np.array([float(r["planner_return"]) for r in rows if int(r["env_steps"]) == last])


def write_summary(rows: list[dict], path: Path) -> None:
    """Writes rows (dicts with the same keys) as a CSV."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def bar_plot(groups: dict[str, dict[str, tuple[float, float]]], path: Path, ylabel: str,
             title: str, lines: dict[str, float] | None = None) -> None:  # fmt: skip
    """Grouped bars: {group (x tick): {series: (mean, std)}}; optional dashed lines per group."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(groups)
    series = sorted({s for g in groups.values() for s in g})
    width = 0.8 / max(len(series), 1)
    fig, ax = plt.subplots(figsize=(max(4.0, 1.4 * len(names) * len(series) / 2 + 2), 4))
    for i, s in enumerate(series):
        xs = [j + (i - (len(series) - 1) / 2) * width for j in range(len(names))]
        means = [groups[n].get(s, (math.nan, 0))[0] for n in names]
        stds = [groups[n].get(s, (math.nan, 0))[1] for n in names]
        ax.bar(xs, means, width, yerr=stds, label=s, capsize=3)
    for j, n in enumerate(names):
        if lines and n in lines:
            ax.plot([j - 0.45, j + 0.45], [lines[n]] * 2, "k--", linewidth=1)
    ax.set_xticks(range(len(names)), names)
    ax.set(ylabel=ylabel, title=title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def ablation(scale: str, tasks, seeds: int, steps: int | None, root: Path,
             arms: dict[str, dict], title: str) -> list[dict]:  # fmt: skip
    """Runs every arm (scale_config keyword overrides) on every task; writes CSV and PNG."""
    rows, bars, lines = [], {}, {}
    for task in tasks:
        bars[task] = {}
        for arm, overrides in arms.items():
            cfg = scale_config(scale, task, steps=steps, **overrides)
            run_arm(cfg, seeds, root / task / arm, f"{task} {arm}")
            values = final_returns(root / task / arm)
            bars[task][arm] = (values.mean(), values.std())
            rows.append({"task": cfg.train.task, "arm": arm, "scale": scale,
                         "steps": cfg.train.steps, "mean": round(values.mean(), 2),
                         "std": round(values.std(), 2),
                         "seeds": " ".join(f"{v:.2f}" for v in values)})  # fmt: skip
        from sirl_jax.envs import spec

        lines[task] = spec(cfg.train.task).success_bar
    write_summary(rows, root / f"{root.name}.csv")
    bar_plot(bars, root / f"{root.name}.png", "final eval return (planner)", title, lines)
    for r in rows:
        print(r)
    return rows
