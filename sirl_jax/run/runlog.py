"""The run directory and its logs: config.json, versions.json, metrics JSONL/CSV, TensorBoard.

Layout of a run directory (see docs/cli.md):

    config.json        the resolved Config (rewritten on resume if an allowed field changed)
    versions.json      python/jax/... versions, git commit, device; one entry per (re)start
    metrics.jsonl/csv  one row per logged train chunk: env_steps, updates, wall time, metrics
    eval.jsonl/csv     one row per evaluation
    tb/                TensorBoard event files (tensorboardX), `train/*` and `eval/*` scalars
    checkpoints/       orbax checkpoints, one directory per env step (see checkpoint.py)

Everything here runs on the host at chunk boundaries; values are plain Python floats.
"""

from __future__ import annotations

import csv
import datetime
import importlib.metadata
import json
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from sirl_jax.config import Config, config_from_dict
from sirl_jax.hb_compat import CONTACT_SET_LOCOMOTION, NO_HAND_FLOOR, REDUCED

_PACKAGES = (
    "jax", "jaxlib", "mujoco", "mujoco-mjx", "flax", "optax", "orbax-checkpoint", "chex",
    "tyro", "numpy", "tensorboardX", "sirl_jax",
)  # fmt: skip
STREAMS = ("metrics", "eval")


def write_json(path: Path, obj: Any) -> None:
    """Writes JSON atomically (temp file + rename), so a crash never leaves half a file."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(obj, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, path)


class RunDirError(ValueError):
    """A run directory or its config.json is missing, taken, or unreadable."""


def sweep_runs(run_dir: Path) -> list[Path] | None:
    """The run directories of a sweep directory (its sweep.json), or None for any other."""
    path = run_dir / "sweep.json"
    if not path.is_file():
        return None
    return [run_dir / name for name in json.loads(path.read_text())["runs"]]


def load_config(run_dir: Path, sweep_ok: bool = False) -> Config:
    """The config saved in `run_dir/config.json`; RunDirError if absent or invalid, or if
    `run_dir` holds a sweep (unless `sweep_ok`: the sweep's base config). A config
    saved before `train.contact_set` existed reads as "reduced", the set it was trained with, one
    saved before `train.hand_floor` existed as "none" (and, on a task of
    `CONTACT_SET_LOCOMOTION`, with the "reduced" set) and one saved before
    `train.contact_budget` existed as 0 (no budget), and one saved before
    `fasttd3.replay_sampling` existed as "episode" (TD-MPC2's sampler, which FastTD3 used
    then), so it resumes as it ran."""
    runs = None if sweep_ok else sweep_runs(run_dir)
    if runs:
        raise RunDirError(f"{run_dir} is a sweep of {len(runs)} runs, not one run; give one of "
                          f"them, e.g. {runs[0]} (all: {run_dir}/*)")  # fmt: skip
    path = run_dir / "config.json"
    if not path.is_file():
        raise RunDirError(f"{run_dir} is not a run directory (no config.json)")
    try:
        raw = json.loads(path.read_text())
        if isinstance(raw.get("train"), dict):
            raw["train"].setdefault("contact_set", REDUCED)
            if "hand_floor" not in raw["train"]:  # saved before the hands touched the floor
                raw["train"]["hand_floor"] = NO_HAND_FLOOR
                if _short(raw["train"].get("task", "")) in CONTACT_SET_LOCOMOTION:
                    raw["train"]["contact_set"] = REDUCED  # what "hb" was in these scenes
            raw["train"].setdefault("contact_budget", 0)
        agent = raw.get("agent") if isinstance(raw.get("agent"), dict) else {}
        if agent.get("kind") == "fasttd3" and isinstance(agent.get("fasttd3"), dict):
            agent["fasttd3"].setdefault("replay_sampling", "episode")  # drawn TD-MPC2's way
        return config_from_dict(Config, raw, str(path))
    except (TypeError, ValueError) as e:
        raise RunDirError(f"{path} is invalid: {e}") from e


def _short(task: str) -> str:
    """A task id's short name: "h1hand-sit_simple-v0" -> "sit_simple" (aliases pass)."""
    parts = task.split("-")
    return parts[1] if len(parts) == 3 and parts[2].startswith("v") else task


def default_run_dir(task: str, seed: int, root: str = "runs") -> Path:
    """runs/<task>-s<seed>-<UTC time>, with path-unsafe characters of the task replaced."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in task)
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%d-%H%M%S")
    return Path(root) / f"{safe}-s{seed}-{stamp}"


def new_run_dir(run_dir: Path | None, task: str, seed: int) -> Path:
    """`run_dir`, or the default one for the task and seed, checked to be new."""
    run_dir = run_dir or default_run_dir(task, seed)
    check_new_run_dir(run_dir)
    return run_dir


def check_new_run_dir(run_dir: Path) -> None:
    """RunDirError if `run_dir` exists and is not empty (a new run never reuses one)."""
    if run_dir.exists() and (not run_dir.is_dir() or any(run_dir.iterdir())):
        raise RunDirError(
            f"run directory {run_dir} already exists; continue it with --resume {run_dir} "
            "or pick another --run-dir (nothing was changed)"
        )


def _git_commit() -> str | None:
    root = Path(__file__).resolve().parent.parent
    try:
        out = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()  # fmt: skip
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return out + ("-dirty" if dirty else "")


def versions() -> dict:
    """Python and package versions, the git commit of the source tree, and the devices."""
    import jax

    out: dict[str, Any] = {"python": platform.python_version(), "platform": platform.platform()}
    for name in _PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    out["git_commit"] = _git_commit()
    devices = jax.devices()
    out["backend"] = jax.default_backend()
    out["devices"] = [f"{d.platform}:{d.id} {getattr(d, 'device_kind', '')}" for d in devices]
    out["argv"] = sys.argv
    out["started"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    return out


def record_versions(run_dir: Path) -> None:
    """Appends this process's versions to versions.json (a list: one entry per start)."""
    path = run_dir / "versions.json"
    entries = json.loads(path.read_text()) if path.exists() else []
    write_json(path, [*entries, versions()])


class CsvLog:
    """A CSV file whose header grows when a new key appears (the file is then rewritten)."""

    def __init__(self, path: Path):
        self.path = path
        self.header: list[str] = []
        if path.exists() and path.stat().st_size:
            with open(path, newline="") as f:
                self.header = next(csv.reader(f), [])

    def rows(self) -> list[dict]:
        """The rows as dicts of strings ([] when the file does not exist)."""
        if not self.path.exists():
            return []
        with open(self.path, newline="") as f:
            return list(csv.DictReader(f))

    def _rewrite(self, rows: list[dict]) -> None:
        tmp = self.path.with_name(self.path.name + ".tmp")
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, self.header, restval="")
            writer.writeheader()
            writer.writerows(rows)
        os.replace(tmp, self.path)

    def append(self, row: Mapping[str, Any]) -> None:
        new = [k for k in row if k not in self.header]
        if new or not self.path.exists():
            self.header += new
            self._rewrite([*self.rows(), row])
            return
        with open(self.path, "a", newline="") as f:
            csv.DictWriter(f, self.header, restval="").writerow(row)

    def extend(self, rows: list[Mapping[str, Any]]) -> None:
        """Appends several rows (one rewrite at most, when they bring new keys)."""
        new = [k for r in rows for k in r if k not in self.header]
        if new or not self.path.exists():
            self.header += list(dict.fromkeys(new))
            self._rewrite([*self.rows(), *rows])
            return
        with open(self.path, "a", newline="") as f:
            csv.DictWriter(f, self.header, restval="").writerows(rows)

    def drop_after(self, step: int) -> None:
        rows = [r for r in self.rows() if float(r.get("env_steps") or 0) <= step]
        if self.header:
            self._rewrite(rows)


def _drop_jsonl_after(path: Path, step: int) -> None:
    if not path.exists():
        return
    lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
    keep = [ln for ln in lines if json.loads(ln).get("env_steps", 0) <= step]
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("".join(ln + "\n" for ln in keep))
    os.replace(tmp, path)


def read_jsonl(path: str | os.PathLike) -> list[dict]:
    """The rows of a metrics/eval JSONL file (NaN is written as the bare token NaN)."""
    return [json.loads(ln) for ln in Path(path).read_text().splitlines() if ln.strip()]


class RunLog:
    """Writes metric rows to JSONL + CSV + TensorBoard (+ wandb when given a module).

    Args:
      run_dir: an existing run directory.
      tensorboard: write tb/ event files.
      wandb_run: an initialised `wandb` run, or None.
    """

    def __init__(self, run_dir: Path, tensorboard: bool = True, wandb_run: Any = None):
        self.run_dir = run_dir
        self._csv = {s: CsvLog(run_dir / f"{s}.csv") for s in STREAMS}
        self._start = time.time()
        self._tb = None
        if tensorboard:
            from tensorboardX import SummaryWriter

            self._tb = SummaryWriter(str(run_dir / "tb"))
        self._wandb = wandb_run

    def drop_after(self, step: int) -> None:
        """Forgets rows logged past `step` (a resumed run re-logs them from its checkpoint)."""
        for s in STREAMS:
            _drop_jsonl_after(self.run_dir / f"{s}.jsonl", step)
            self._csv[s].drop_after(step)

    def log(self, stream: str, env_steps: int, metrics: Mapping[str, float]) -> dict:
        """Appends one row to `stream` ('metrics' or 'eval'); returns the row written."""
        if stream not in STREAMS:
            raise ValueError(f"stream must be one of {STREAMS}, got {stream!r}")
        row = {"env_steps": int(env_steps), "wall_time": round(time.time() - self._start, 3)}
        row.update({k: float(v) for k, v in metrics.items() if k != "env_steps"})
        with open(self.run_dir / f"{stream}.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")
        self._csv[stream].append(row)
        prefix = "train" if stream == "metrics" else "eval"
        scalars = {k if "/" in k else f"{prefix}/{k}": v for k, v in row.items()}
        scalars.pop(f"{prefix}/env_steps")
        if self._tb is not None:
            for k, v in scalars.items():
                if math.isfinite(v):
                    self._tb.add_scalar(k, v, global_step=int(env_steps))
            self._tb.flush()
        if self._wandb is not None:
            self._wandb.log(scalars, step=int(env_steps))
        return row

    def writers(self) -> tuple[Any, Any]:
        """(the TensorBoard writer or None, the wandb run or None): for what is not a scalar."""
        return self._tb, self._wandb

    def close(self) -> None:
        if self._tb is not None:
            self._tb.close()
        if self._wandb is not None:
            self._wandb.finish()


def agent_line(a, iterations: str, sirl: str) -> str:
    """The run header's agent line, for either learner."""
    if a.kind == "fasttd3":
        f = a.fasttd3
        return (f"agent: FastTD3 (actor {f.actor_hidden_dim}, critic {f.critic_hidden_dim}, "
                f"{f.num_atoms} atoms on [{f.v_min:g}, {f.v_max:g}]), n-step {f.n_steps}, "
                f"{f.num_updates} critic updates per step, batch {f.batch_size}, {sirl}")
    arch = a.arch
    return (f"agent: {a.model_size} (enc {arch.enc_dim}, mlp {arch.mlp_dim}, latent "
            f"{arch.latent_dim}, {arch.num_q} Qs), H={a.horizon}, MPPI {iterations} it x "
            f"{a.num_samples} samples, batch {a.batch_size}, {sirl}")


def describe_run(
    config: Config,
    spec: Any,
    buffer_line: str,
    run_dir: Path,
    iterations: int,
    derived: Mapping[str, tuple] | None = None,
) -> str:
    """The resolved-config lines printed before a run starts.

    iterations: the MPPI iterations the agent runs (`Agent.iterations`: +2 when the action
    size is >= 20). derived: {field: (preset value, value used)} that `fit_to_task` raised.
    """
    import jax

    t, a = config.train, config.agent
    its = iterations
    its_text = f"{its}" if its == a.iterations else f"{its} ({a.iterations} + 2 for A >= 20)"
    plain = "plain TD-MPC2" if a.kind == "tdmpc2" else "plain FastTD3"
    sirl = (f"{'TDMPBC' if a.kind == 'tdmpc2' else 'SIRL'} beta={a.sirl.beta:g} "
            f"G={a.sirl.g_source} ({a.sirl.bc_form})" if a.sirl.enabled
            else f"{plain} (no BC term)")  # fmt: skip
    bar = "none" if spec.success_bar is None else f"{spec.success_bar:g}"
    every = lambda n: f"{n:,}" if n else "never"
    fitted = [f"sized for T={spec.episode_length}: " + ", ".join(
        f"{k} {old:,} -> {new:,}" for k, (old, new) in derived.items())] if derived else []
    return "\n".join([
        f"task {spec.id} (T={spec.episode_length}, success bar {bar}), seed {t.seed}, "
        f"{t.steps:,} env steps, E={t.num_envs} x K={t.chunk_steps} per call, utd {t.utd:g}",
        agent_line(a, its_text, sirl),
        buffer_line,
        f"run dir {run_dir}: eval every {every(t.eval_every)}, checkpoint every "
        f"{every(t.checkpoint_interval)} (buffer {'saved' if t.save_buffer else 'not saved'}), "
        f"log every {t.log_every:,}",
        *fitted,
        f"device: {jax.default_backend()} ({jax.devices()[0].device_kind}, "
        f"{jax.device_count()} device(s))",
    ])  # fmt: skip
