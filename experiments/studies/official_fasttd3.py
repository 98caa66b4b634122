"""The official FastTD3 on HumanoidBench's own env, at the parallel-learner study's config.

Runs `fast_td3/train.py` of a FastTD3 checkout (public repository younggyoseo/FastTD3,
extracted) under a venv with HumanoidBench, PyTorch (CPU), jax, tensordict, stable-baselines3,
loguru, tyro and wandb (REFENV: HumanoidBench's own pins, see docs/tasks.md, plus those),
on `h1hand-sit_simple-v0` at the `fasttd3-cpu` preset's sizes: 32 envs, batch 1024 in all
(FastTD3 samples batch / envs per env), critic 512 and actor 256 wide, float32, no
`torch.compile`, no CUDA.

    .venv/bin/python -m experiments.studies.official_fasttd3 --checkout FASTTD3 \\
        --python REFENV/bin/python [--hb-checkout HUMANOID_BENCH] \\
        [--out docs/results/parallel_learner/official_fasttd3/eval.csv]

It writes `--out` (env_steps, return, length, wall_s: one row per evaluation) and console.log
beside it. FastTD3 evaluates its deterministic actor on its training envs (one episode each)
every `eval_interval` vector steps, and only where the step is also a multiple of 100, so
`--eval-every` is rounded to a multiple of 100 vector steps (300 at 32 envs: every 9,600 env
steps). A rerun starts over.

Patches, applied in the child by `CHILD` before `train.py` runs (the checkout is not edited):
1. FastTD3 reports evaluations only through wandb: `wandb.init` is a no-op and `wandb.log`
   prints a line `EVAL env_steps=... return=... length=... wall_s=...` for each log that holds
   an evaluation (`official_rows` reads them back).
2. Its SubprocVecEnv starts the env processes with `fork`: with the default start method, each
   of the 32 processes imports HumanoidBench (which imports torch and jax) anew, and the run
   went out of memory on a 24 GB machine.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time
from pathlib import Path

import tyro

from sirl_jax.presets import get_preset
from sirl_jax.run.runlog import CsvLog

TASK = "h1hand-sit_simple-v0"

CHILD = r"""
import functools, os, runpy, sys, time
root, hb = sys.argv[1], sys.argv[2]
sys.path[:0] = [os.path.join(root, "fast_td3")] + ([hb] if hb else [])
t0 = time.time()
import wandb


def log(d, step=None):
    if "eval_avg_return" in d:
        print(f"EVAL env_steps={int(d['frame'])} return={float(d['eval_avg_return']):.3f} "
              f"length={float(d['eval_avg_length']):.1f} wall_s={time.time() - t0:.0f}",
              flush=True)


wandb.init, wandb.log = (lambda *a, **k: None), log
import torch, tensordict  # train.py's import order: tensordict after jax crashes (SIGSEGV)
from environments import humanoid_bench_env as E
E.SubprocVecEnv = functools.partial(E.SubprocVecEnv, start_method="fork")
sys.argv = ["train.py", *sys.argv[3:]]
runpy.run_path(os.path.join(root, "fast_td3", "train.py"), run_name="__main__")
"""


def official_rows(log: Path) -> list[dict]:
    """The evaluations in an official FastTD3 console log: its `EVAL env_steps=N return=R
    length=L wall_s=T` lines (`CHILD`'s `wandb.log`), tqdm's carriage returns split off."""
    rows = []
    for line in log.read_text(errors="replace").replace("\r", "\n").splitlines():
        if line.startswith("EVAL "):
            rows.append({k: float(v) for k, v in (kv.split("=") for kv in line.split()[1:])})
    return rows


@dataclasses.dataclass(frozen=True)
class Args:
    checkout: str
    """FastTD3's repository, extracted (holds fast_td3/train.py)."""
    python: str
    """REFENV's python (see the module docstring)."""
    hb_checkout: str = ""
    """HumanoidBench's repository, where REFENV does not have humanoid_bench installed."""
    out: str = "results/parallel_learner/official_fasttd3/eval.csv"
    seed: int = 1
    steps: int = 200_000
    """Env steps in all (over the envs)."""
    num_envs: int = 32
    eval_every: int = 10_000
    """Env steps between evaluations, rounded to a multiple of 100 vector steps."""


def command(a: Args) -> list[str]:
    """train.py's flags: the `fasttd3-cpu` preset's sizes, FastTD3's defaults otherwise."""
    f = get_preset("fasttd3-cpu").agent.fasttd3
    eval_interval = max(100, round(a.eval_every / a.num_envs / 100) * 100)
    return [f"--env_name={TASK}", f"--seed={a.seed}", f"--num_envs={a.num_envs}",
            f"--total_timesteps={a.steps // a.num_envs + 10}", f"--batch_size={f.batch_size}",
            f"--critic_hidden_dim={f.critic_hidden_dim}",
            f"--actor_hidden_dim={f.actor_hidden_dim}", f"--eval_interval={eval_interval}",
            "--render_interval=0", "--save_interval=0", "--no-cuda", "--no-compile", "--no-amp",
            "--use_wandb"]  # fmt: skip


def main(a: Args) -> None:
    checkout = Path(a.checkout).resolve()
    if not (checkout / "fast_td3" / "train.py").exists():
        raise SystemExit(f"error: {checkout} has no fast_td3/train.py (see the docstring)")
    if not Path(a.python).exists():
        raise SystemExit(f"error: {a.python} does not exist (see the docstring for the venv)")
    eval_csv = Path(a.out).resolve()
    folder = eval_csv.parent
    folder.mkdir(parents=True, exist_ok=True)
    hb = str(Path(a.hb_checkout).resolve()) if a.hb_checkout else ""
    cmd = [a.python, "-c", CHILD, str(checkout), hb, *command(a)]
    print(f"official FastTD3: train.py {' '.join(cmd[5:])}\n  in {folder}", flush=True)
    start = time.perf_counter()
    # train.py's own settings, which it makes before its imports: CHILD imports torch
    # before train.py runs, so they are made here
    env = dict(os.environ, PYTHONUNBUFFERED="1", MUJOCO_GL="egl", WANDB_MODE="disabled",
               OMP_NUM_THREADS="1", TORCHDYNAMO_INLINE_INBUILT_NN_MODULES="1",
               XLA_PYTHON_CLIENT_PREALLOCATE="false", JAX_DEFAULT_MATMUL_PRECISION="highest")
    with open(folder / "console.log", "w") as log:
        child = subprocess.Popen(cmd, cwd=folder, env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, text=True, bufsize=1)  # fmt: skip
        assert child.stdout is not None
        for line in child.stdout:
            sys.stdout.write(line)
            log.write(line)
            log.flush()
        rc = child.wait()
    eval_csv.unlink(missing_ok=True)
    CsvLog(eval_csv).extend(official_rows(folder / "console.log"))
    print(f"official FastTD3: exit {rc} after {time.perf_counter() - start:.0f} s; evals in "
          f"{eval_csv}", flush=True)  # fmt: skip
    if rc:
        raise SystemExit(rc)


if __name__ == "__main__":
    main(tyro.cli(Args))
