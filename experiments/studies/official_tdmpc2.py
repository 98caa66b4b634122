"""The official TD-MPC2 on HumanoidBench's own env, at the sit_simple study's config: one seed.

The reference learner of the sit_simple study (`experiments.study sit_simple`): HumanoidBench's
PyTorch fork of TD-MPC2 (its `tdmpc2/` folder), trained on HumanoidBench's MuJoCo C env
h1hand-sit_simple-v0, so that its eval curve can be laid beside ours. Nothing of it is copied
here: the fork runs from a checkout outside this repository, in a venv of its own, and this
module only launches it, applies the few compatibility patches below in the child process at
run time (the checkout stays as extracted), and writes the evals in our CSV format.

Setup (once; SNAPSHOT is a git directory of carlosferrazza/humanoid-bench, CHECKOUT and REFENV
any two folders outside the repository)::

    # the checkout: HumanoidBench's repository at 791405f (the snapshot's HEAD). Eight blobs
    # (data/reach_*/{mean,var}.npy, three kitchen/plywood PNGs, logs/main_results.json) are
    # absent from the snapshot and not needed by this task, so they are excluded (git still
    # prints one "invalid object" error for them; the extraction is complete and exits 0):
    mkdir -p CHECKOUT
    git -C SNAPSHOT archive HEAD -- . $(for p in data/reach_one_hand/mean.npy \\
        data/reach_one_hand/var.npy data/reach_two_hands/mean.npy data/reach_two_hands/var.npy \\
        humanoid_bench/assets/kitchen/adept_models/kitchen/textures/wood1.png \\
        humanoid_bench/assets/tasks/assets/kitchen-wood.png \\
        humanoid_bench/assets/tasks/assets/plywood-4k.png logs/main_results.json; \\
        do echo ":(exclude)$p"; done) | tar -x -C CHECKOUT
    # the venv: the CPU torch wheel, then the newest tensordict/torchrl that take it, and
    # HumanoidBench's pins where the env needs them (gymnasium 0.29.1's MujocoEnv API, the
    # mujoco/dm_control pair of its setup.py); numpy < 2 for gymnasium 0.29.1's env checker
    python3 -m venv REFENV
    REFENV/bin/pip install torch==2.13.0+cpu  # the CPU wheel (not PyPI's CUDA build)
    REFENV/bin/pip install "numpy<2" tensordict torchrl gymnasium==0.29.1 mujoco==3.1.6 \\
        dm_control==1.0.20 hydra-core==1.3.2 hydra-submitit-launcher==1.2.0 termcolor pandas \\
        jax imageio
    REFENV/bin/pip install --no-deps -e CHECKOUT -e CHECKOUT/tdmpc2
    # what this resolved to: torch 2.13.0+cpu, tensordict 0.14.3, torchrl 0.14.1, numpy
    # 1.26.4, gymnasium 0.29.1, mujoco 3.1.6, dm_control 1.0.20, hydra-core 1.3.2, omegaconf
    # 2.3.1, jax 0.7.1 (humanoid_bench imports jax.numpy at import time), pandas 3.0.6

Run (the study's 100k env steps; about 2.5 hours on 2 busy cores, see the measured rate below)::

    .venv/bin/python -m experiments.studies.official_tdmpc2 --checkout CHECKOUT \\
        --python REFENV/bin/python

It writes `--out` (default results/sit_simple/official/eval.csv; one row per eval, as it
happens), train.csv (one row per training episode) and console.log beside it, and the fork's
own logs (its eval.csv, hydra's config dump) under logs/ and hydra/ there. A rerun starts over:
the fork cannot resume.

The fork's overrides (everything else at its config.yaml defaults): the study's
`AgentConfig.small` agent (latent 64, MLP 128, encoder 64 with 2 layers, 2 Qs, SimNorm groups of
8, 101 bins), MPPI 64 samples x 2 iterations with 8 elites and 8 policy trajectories (both the
fork and we add 2 iterations for the 61-dim action: 4 in effect), horizon 3, batch 64,
4,000 seed steps, a 100k buffer, eval every 10k env steps over 4 episodes, no wandb, no
video. `model_size` is left unset (`???` in the fork's config): its parser then applies no
preset, so the explicit widths above are the ones built (the child prints them and the
parameter count at start).

Differences from our runs that stay:
- we step 4 envs per seed with one update per env step (4 per vector step); the fork steps one
  env, one update per env step, plus `seed_steps` updates in one go when the seed phase ends
  (ours: none in one go). Both do about 100k updates over 100k env steps.
- the fork evaluates at the first episode end at or after each multiple of `eval_freq`, so an
  eval row's env_steps can be a little past 10k, 20k, ...; ours are at the multiples. Its loop
  ends at `steps` and so would mostly miss the last eval: it is given `steps` + 1,000 (one
  episode) and the child stops right after the first eval at or past `--steps`.
- the fork's eval has the planner only: policy_return / policy_length stay empty.
- `--seed` seeds torch, numpy and random, but the fork never passes a seed to `env.reset`, so
  the env's own randomness is not fixed: two smoke runs at seed 0 gave different step-0 evals.

CSV columns (our `eval.csv`'s): planner_return = the fork's eval episode_reward (mean over the
eval episodes); planner_length = the mean eval episode length (counted by a wrapper around the
env's step during eval); r_max = the best training episode return so far (with the buffer as
large as the run, the buffer's R_max); wall_s = seconds since the child started; cpu_s = the
child's process CPU time (all its threads) less the CPU time spent in evals, as our cpu_s.

Compatibility patches, applied in the child by `CHILD` below before the fork's `train()` runs
(the checkout is not edited):
1. CPU replay buffer: `tdmpc2/common/buffer.py` hard-codes `torch.device("cuda")` as the batch
   device off macOS and asks `torch.cuda.mem_get_info()` to place its storage. Buffer.__init__
   is wrapped to set `_device` to the CPU, and without CUDA `torch.cuda.mem_get_info` returns
   (0, 0), so its heuristic picks CPU storage.
2. No pinned memory: the buffer builds torchrl's `ReplayBuffer(pin_memory=True, ...)`, which
   needs an accelerator with torchrl 0.14; the module's `ReplayBuffer` is replaced by a wrapper
   that passes `pin_memory=False` (everything else as given).
3. seed_steps: the fork's `envs.make_env` overwrites `cfg.seed_steps` with
   max(1000, 5 x episode length) = 5,000 for this task; the `make_env` that train.py calls is
   wrapped to put back a `seed_steps=N` given on the command line (the study's 4,000).
The agent (tdmpc2.py) needs none: it picks the CPU itself when CUDA is absent.

Besides the patches, three wrappers only observe: one around OnlineTrainer.eval (eval episode
lengths, eval CPU time), one around TDMPC2.update (an update count), and one around
Logger.log, which appends our CSV rows and prints a progress line (env steps, steps/s, ETA).

Measured on the 2-core CPU machine beside the sit_simple study (load average 5.6-6, this run
at nice 5, torch's default 2 threads), `--steps 3000 --seed-steps 1000 --eval-freq 100000
--eval-episodes 1`: after the seed phase, 85 s wall and 80 s CPU per 1k env steps (one update
and one MPPI plan per step); the seed-phase updates in one go cost about 49 ms CPU each (about
200 s for the study's 4,000); start-up (imports, the first eval) about 100 s of wall-clock.
So 100k env steps take about 96 x 85 s = 2.3 hours plus the evals (4 planner episodes each).
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time
from pathlib import Path

import tyro

TASK = "humanoid_h1hand-sit_simple-v0"  # the fork's envs/humanoid.py: "humanoid_" + gym id
EPISODE = 1_000  # the task's episode length (HumanoidBench's max_episode_steps)

EVAL_HEADER = ("seed,env_steps,wall_s,planner_return,planner_length,policy_return,policy_length,"
               "r_max,cpu_s")  # fmt: skip
TRAIN_HEADER = "seed,env_steps,wall_s,episode_return,episode_length,r_max,updates,cpu_s"

# The child: patches (see the module docstring), observers, then the fork's hydra entry point,
# which reads the overrides from sys.argv. Settings come in OFFICIAL_TDMPC2_* variables.
CHILD = r"""
import csv, functools, math, os, sys, time
T0 = time.perf_counter()
import torch
import tdmpc2.train as fork_train
from tdmpc2.common import buffer as fork_buffer
from tdmpc2.common.logger import Logger
from tdmpc2.tdmpc2 import TDMPC2
from tdmpc2.trainer.online_trainer import OnlineTrainer

EVAL_CSV, TRAIN_CSV = os.environ["OFFICIAL_TDMPC2_EVAL"], os.environ["OFFICIAL_TDMPC2_TRAIN"]
EVAL_HEADER, TRAIN_HEADER = os.environ["OFFICIAL_TDMPC2_EVAL_HEADER"], \
    os.environ["OFFICIAL_TDMPC2_TRAIN_HEADER"]
PROGRESS_S = float(os.environ.get("OFFICIAL_TDMPC2_PROGRESS_S", "60"))
TARGET = int(os.environ["OFFICIAL_TDMPC2_STEPS"])  # stop after the first eval at or past it

# patch 1: the replay buffer's batches and storage on the CPU
_buffer_init = fork_buffer.Buffer.__init__
def buffer_init(self, cfg):
    _buffer_init(self, cfg)
    self._device = torch.device("cpu")
fork_buffer.Buffer.__init__ = buffer_init
if not torch.cuda.is_available():
    torch.cuda.mem_get_info = lambda *a, **k: (0, 0)

# patch 2: no pinned memory
_replay_buffer = fork_buffer.ReplayBuffer
def replay_buffer(*args, **kwargs):
    kwargs["pin_memory"] = False
    return _replay_buffer(*args, **kwargs)
fork_buffer.ReplayBuffer = replay_buffer

# patch 3: a seed_steps given on the command line survives make_env
_make_env = fork_train.make_env
def make_env(cfg):
    want = cfg.get("seed_steps", None)
    env = _make_env(cfg)
    if want is not None:
        cfg.seed_steps = int(want)
    return env
fork_train.make_env = make_env

# observers
S = dict(eval_cpu=0.0, updates=0, r_max=-math.inf, seed=0, steps=0, seed_steps=0,
         last_print=-math.inf, rate_from=None, eval=None)

def cpu_s():
    return time.process_time() - S["eval_cpu"]

_agent_init = TDMPC2.__init__
def agent_init(self, cfg):
    _agent_init(self, cfg)
    S.update(seed=int(cfg.seed), steps=TARGET, seed_steps=int(cfg.seed_steps))
    n = sum(p.numel() for p in self.model.parameters())
    keys = ("latent_dim", "mlp_dim", "enc_dim", "num_enc_layers", "num_q", "simnorm_dim",
            "num_bins", "horizon", "iterations", "num_samples", "num_elites", "num_pi_trajs",
            "batch_size", "seed_steps", "buffer_size", "steps", "eval_freq", "eval_episodes",
            "episode_length", "action_dim", "obs_shape", "model_size", "seed")
    print("[official] resolved config: " + ", ".join(f"{k}={cfg.get(k, None)}" for k in keys)
          + f"; {n:,} parameters; device {self.device}; torch threads "
          + f"{torch.get_num_threads()}", flush=True)
TDMPC2.__init__ = agent_init

_update = TDMPC2.update
def update(self, buffer):
    S["updates"] += 1
    return _update(self, buffer)
TDMPC2.update = update

_eval = OnlineTrainer.eval
def eval_(self):
    c0, n, step = time.process_time(), [0], self.env.step
    def counted(action):
        n[0] += 1
        return step(action)
    self.env.step = counted
    try:
        out = _eval(self)
    finally:
        del self.env.step
        S["eval_cpu"] += time.process_time() - c0
    out["episode_length"] = n[0] / self.cfg.eval_episodes
    return out
OnlineTrainer.eval = eval_

for path, header in ((EVAL_CSV, EVAL_HEADER), (TRAIN_CSV, TRAIN_HEADER)):
    with open(path, "w") as f:
        f.write(header + "\n")

def append(path, row):
    with open(path, "a", newline="") as f:
        csv.writer(f).writerow(row)

def fmt(x, nd=3):
    return "" if x is None or not math.isfinite(float(x)) else round(float(x), nd)

def progress(step, force=False):
    now = time.perf_counter()
    if not force and now - S["last_print"] < PROGRESS_S:
        return
    S["last_print"] = now
    if S["rate_from"] is None and step > S["seed_steps"]:
        S["rate_from"] = (now, step)
    rate = eta = ""
    if S["rate_from"] is not None and step > S["rate_from"][1]:
        sps = (step - S["rate_from"][1]) / (now - S["rate_from"][0])
        rate = f", {1000 / sps:.0f} s per 1k env steps"
        eta = f", ETA {max(S['steps'] - step, 0) / sps / 3600:.2f} h"
    ev = "" if S["eval"] is None else f", last eval {S['eval'][1]:.1f} @ {S['eval'][0]:,}"
    print(f"[official] env step {step:,}/{S['steps']:,}, {S['updates']:,} updates, R_max "
          f"{S['r_max']:.1f}{ev}, {now - T0:.0f} s wall, {cpu_s():.0f} s CPU{rate}{eta}",
          flush=True)

_log = Logger.log
def log(self, d, category="train"):
    _log(self, d, category)
    wall = time.perf_counter() - T0
    if category == "results":
        ret = float(d["return"])
        S["r_max"] = max(S["r_max"], ret)
        append(TRAIN_CSV, [S["seed"], int(d["step"]), round(wall, 1), fmt(ret),
                           int(d["episode_length"]), fmt(S["r_max"]), S["updates"],
                           round(cpu_s(), 1)])
        progress(int(d["step"]))
    elif category == "eval":
        step, ret = int(d["step"]), float(d["episode_reward"])
        S["eval"] = (step, ret)
        r_max = S["r_max"] if math.isfinite(S["r_max"]) else None
        append(EVAL_CSV, [S["seed"], step, round(wall, 1), fmt(ret),
                          fmt(d["episode_length"], 2), "", "", fmt(r_max), round(cpu_s(), 1)])
        progress(step, force=True)
        if step >= TARGET:  # the run's last eval: stop here (the fork would train on to steps)
            print(f"[official] the eval at {step:,} env steps is the last (--steps {TARGET:,}); "
                  "stopping", flush=True)
            sys.stdout.flush()
            os._exit(0)
Logger.log = log

fork_train.train()
"""


@dataclasses.dataclass(frozen=True)
class Args:
    checkout: str
    """HumanoidBench's repository, extracted (its tdmpc2/ folder is the fork)."""
    python: str
    """The fork's venv's python (see the module docstring for its setup)."""
    out: str = "results/sit_simple/official/eval.csv"
    """Our eval CSV; train.csv, console.log and the fork's logs go beside it."""
    seed: int = 0
    steps: int = 100_000
    """Env steps; a multiple of --eval-freq, so that the run's last eval is at (or just past) it."""
    seed_steps: int = 4_000
    """The study's: one episode length per env, 4 envs."""
    eval_freq: int = 10_000
    eval_episodes: int = 4
    buffer_size: int = 100_000
    threads: int = 0
    """> 0: torch intra-op threads of the child (OMP_NUM_THREADS); 0: torch's default."""
    progress_s: float = 60.0
    """Least seconds between two progress lines (every eval prints one too)."""


def overrides(a: Args) -> list[str]:
    """The fork's hydra overrides: the study's agent (`AgentConfig.small`) and budget."""
    agent = dict(latent_dim=64, mlp_dim=128, enc_dim=64, num_enc_layers=2, num_q=2,
                 simnorm_dim=8, num_bins=101, horizon=3, iterations=2, num_samples=64,
                 num_elites=8, num_pi_trajs=8, batch_size=64)  # fmt: skip
    run = dict(task=TASK, seed=a.seed, steps=a.steps + EPISODE, seed_steps=a.seed_steps,
               eval_freq=a.eval_freq, eval_episodes=a.eval_episodes, buffer_size=a.buffer_size,
               exp_name="official", disable_wandb="true", save_video="false")  # fmt: skip
    out = Path(a.out).resolve().parent
    return [f"{k}={v}" for k, v in {**agent, **run}.items()] + [f"hydra.run.dir={out / 'hydra'}"]


def main(a: Args) -> None:
    checkout, python = Path(a.checkout).resolve(), Path(a.python)
    if not (checkout / "tdmpc2" / "tdmpc2" / "train.py").exists():
        raise SystemExit(f"error: {checkout} has no tdmpc2/tdmpc2/train.py (see the docstring)")
    if not python.exists():
        raise SystemExit(f"error: {python} does not exist (see the docstring for the venv)")
    eval_csv = Path(a.out).resolve()
    folder = eval_csv.parent
    folder.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, OFFICIAL_TDMPC2_EVAL=str(eval_csv),
               OFFICIAL_TDMPC2_TRAIN=str(folder / "train.csv"),
               OFFICIAL_TDMPC2_EVAL_HEADER=EVAL_HEADER, OFFICIAL_TDMPC2_TRAIN_HEADER=TRAIN_HEADER,
               OFFICIAL_TDMPC2_PROGRESS_S=str(a.progress_s), OFFICIAL_TDMPC2_STEPS=str(a.steps),
               PYTHONUNBUFFERED="1",
               HYDRA_FULL_ERROR="1")  # fmt: skip
    if a.threads > 0:
        env["OMP_NUM_THREADS"] = env["MKL_NUM_THREADS"] = str(a.threads)
    cmd = [str(python), "-c", CHILD, *overrides(a)]
    print(f"official TD-MPC2: {python} -c CHILD {' '.join(cmd[3:])}\n  in {folder}", flush=True)
    start = time.perf_counter()
    with open(folder / "console.log", "w") as log:
        child = subprocess.Popen(cmd, cwd=folder, env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, text=True, bufsize=1)  # fmt: skip
        assert child.stdout is not None
        for line in child.stdout:
            sys.stdout.write(line)
            log.write(line)
            log.flush()
        rc = child.wait()
    took = time.perf_counter() - start
    print(f"official TD-MPC2: exit {rc} after {took:.0f} s; evals in {eval_csv}", flush=True)
    if rc:
        raise SystemExit(rc)


if __name__ == "__main__":
    main(tyro.cli(Args))
