"""The CLI shell on real runs: run-dir contents, Ctrl-C + resume == uninterrupted, eval and
report of a run, and the bad input that needs one (the rest: test_cli_input.py).

The real runs use the smoke preset shrunk further (pendulum, 2 envs, 25 steps per env per
chunk, 650 env steps) and share one compiled train step through the compilation cache.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import signal
from pathlib import Path

import jax
import numpy as np
import pytest

from sirl_jax.envs import load
from sirl_jax.run import cli, progress, runlog, runner
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.states import restore_state

STEPS, STOP_AT, PER_CALL = 650, 550, 50
BASE = [
    "--preset", "smoke", "--steps", str(STEPS), "--seed-steps", "200", "--chunk-steps", "25",
    "--num-envs", "2", "--eval-every", str(STEPS), "--log-every", str(PER_CALL),
    "--checkpoint-every", "0", "--no-progress",
]  # fmt: skip


def _listing(root: Path) -> dict[str, bytes]:
    files = sorted(p for p in root.rglob("*") if p.is_file())
    return {str(p.relative_to(root)): p.read_bytes() for p in files}


def _rows(path: Path) -> list[dict]:
    """The rows of a JSONL log without their clocks (wall_time; a sweep's time/*)."""
    return [{k: v for k, v in r.items() if k != "wall_time" and not k.startswith("time/")}
            for r in runlog.read_jsonl(path)]  # fmt: skip


def _same(a, b) -> bool:
    both_nan = isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)
    return a == b or both_nan


def _load_final(run_dir: Path):
    """The newest checkpoint's state and buffer leaves, restored against its own layout."""
    from sirl_jax.train import make_train

    config = runlog.load_config(run_dir)
    trainer = make_train(config, load(config.train.task)[1])
    ckpt = Checkpointer(run_dir / "checkpoints")
    state, step = restore_state(ckpt, trainer.init, jax.random.PRNGKey(config.train.seed))
    ckpt.close()
    return step, jax.tree.leaves(state)


def train_interrupted(argv: list[str], stop_at: int) -> tuple[int, list[int]]:
    """`train argv` with a Ctrl-C (SIGINT) sent after the first chunk reaching `stop_at` env
    steps; returns (exit code, [env steps at which it was sent])."""
    original, sent = progress.Progress.update, []

    def interrupt_once(self, env_steps, updates, metrics):
        original(self, env_steps, updates, metrics)
        if env_steps >= stop_at and not sent:
            sent.append(env_steps)
            os.kill(os.getpid(), signal.SIGINT)

    progress.Progress.update = interrupt_once
    try:
        return cli.main(["train", *argv]), sent
    finally:
        progress.Progress.update = original


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Run A: uninterrupted. Run B: Ctrl-C after the chunk ending at STOP_AT, then --resume."""
    root = tmp_path_factory.mktemp("runs")
    a, b = root / "a", root / "b"
    assert cli.main(["train", *BASE, "--run-dir", str(a)]) == 0

    stopped, sent = train_interrupted([*BASE, "--run-dir", str(b)], STOP_AT)
    steps_after_stop = Checkpointer(b / "checkpoints").steps()
    resumed = cli.main(["train", "--resume", str(b), "--no-progress"])
    return {"a": a, "b": b, "stopped": stopped, "resumed": resumed, "sent": sent,
            "steps_after_stop": steps_after_stop}  # fmt: skip


@pytest.mark.timeout(600)
def test_ctrl_c_then_resume_equals_uninterrupted_run(runs):
    assert runs["stopped"] == 0 and runs["resumed"] == 0
    assert runs["sent"] == [STOP_AT] and runs["steps_after_stop"] == [STOP_AT]
    step_a, leaves_a = _load_final(runs["a"])
    step_b, leaves_b = _load_final(runs["b"])
    assert step_a == step_b == STEPS
    assert len(leaves_a) == len(leaves_b)
    for x, y in zip(leaves_a, leaves_b, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    for stream in ("metrics.jsonl", "eval.jsonl"):
        rows_a, rows_b = _rows(runs["a"] / stream), _rows(runs["b"] / stream)
        assert [r["env_steps"] for r in rows_a] == [r["env_steps"] for r in rows_b]
        for ra, rb in zip(rows_a, rows_b, strict=True):
            assert ra.keys() == rb.keys()
            assert all(_same(ra[k], rb[k]) for k in ra), (ra, rb)
    # the run learned something: updates happened before the interruption point
    assert _rows(runs["a"] / "metrics.jsonl")[-1]["updates"] > 0


@pytest.mark.timeout(120)
def test_run_dir_layout(runs):
    a = runs["a"]
    config = runlog.load_config(a)
    assert config.train.steps == STEPS and config.train.task == "pendulum"
    versions = json.loads((a / "versions.json").read_text())
    assert len(versions) == 1 and {"python", "jax", "jaxlib", "mujoco", "orbax-checkpoint",
                                   "git_commit", "devices"} <= versions[0].keys()  # fmt: skip
    assert len(json.loads((runs["b"] / "versions.json").read_text())) == 2  # start + resume
    rows = runlog.read_jsonl(a / "metrics.jsonl")
    assert [r["env_steps"] for r in rows] == list(range(PER_CALL, STEPS + 1, PER_CALL))
    csv_lines = (a / "metrics.csv").read_text().splitlines()
    assert len(csv_lines) == len(rows) + 1 and "nonfinite_loss" in csv_lines[0]
    assert [r["env_steps"] for r in runlog.read_jsonl(a / "eval.jsonl")] == [STEPS]
    assert list((a / "tb").glob("events.out.tfevents.*"))
    assert Checkpointer(a / "checkpoints").steps() == [STEPS]


@pytest.mark.slow  # 1.8 min: the eval command's compile and a direct evaluate
@pytest.mark.timeout(300)
def test_eval_command_reproduces_the_logged_evaluation(runs, capsys):
    """`eval RUN_DIR --episodes 1` (the run's own eval size) writes the numbers the run logged,
    and they equal a direct `Train.evaluate` call on the restored state with the same key."""
    from sirl_jax.train import make_train

    capsys.readouterr()
    assert cli.main(["eval", str(runs["a"]), "--episodes", "1"]) == 0
    table = capsys.readouterr().out
    assert f"{STEPS:,}" in table and "random policy: return" in table
    with open(runs["a"] / "eval" / "checkpoints.csv", newline="") as f:
        written = list(csv.DictReader(f))
    assert [int(r["env_steps"]) for r in written] == [STEPS]
    out = {k: float(v) for k, v in written[0].items() if k.startswith("eval/")}
    logged = _rows(runs["a"] / "eval.jsonl")[-1]
    for k, v in logged.items():
        if k != "env_steps":
            assert _same(out[k], v), k
    config = runlog.load_config(runs["a"])
    trainer = make_train(config, load(config.train.task)[1])
    ckpt = Checkpointer(runs["a"] / "checkpoints")
    state, step = restore_state(ckpt, trainer.init, jax.random.PRNGKey(config.train.seed))
    ckpt.close()
    direct = jax.device_get(trainer.evaluate(state, runner.eval_key(config.train.seed, step)))
    for k in ("eval/planner_return", "eval/policy_return", "eval/policy_length"):
        assert out[k] == pytest.approx(float(direct[k]), rel=1e-5), k
    assert any(k.startswith("eval/policy_term/") for k in out)
    with open(runs["a"] / "eval" / "random.csv", newline="") as f:
        assert float(next(csv.DictReader(f))["eval/random_length"]) > 0


@pytest.mark.timeout(120)
def test_report_of_a_real_run(runs, tmp_path, capsys):
    """`report` on run A (after or before `eval`): one self-contained page, nothing written in
    the run dir when --out points elsewhere."""
    before = _listing(runs["a"])
    out = tmp_path / "report.html"
    capsys.readouterr()
    assert cli.main(["report", str(runs["a"]), "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    page = out.read_text()
    assert "pendulum" in page and f"last {STEPS:,}" in page and "data:image/png;base64," in page
    assert "env blow-ups" in page and "env steps/s" in page and "train.num_envs" in page
    assert _listing(runs["a"]) == before


@pytest.mark.timeout(120)
def test_eval_bad_input_gives_one_line(runs, tmp_path, capsys):
    cases = [
        ([str(tmp_path / "nope")], "does not exist"),
        ([str(runs["a"]), "--step", "7"], "--step 7: no checkpoint at that env step; available"),
        ([str(runs["a"]), "--episodes", "0"], "--episodes=0 is invalid"),
    ]
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "config.json").write_text((runs["a"] / "config.json").read_text())
    cases.append(([str(empty)], "has no checkpoints/"))
    other = tmp_path / "other"
    shutil.copytree(runs["a"], other)
    cfg = json.loads((other / "config.json").read_text())
    cfg["agent"]["latent_dim"] = 64  # a config the saved networks do not match
    (other / "config.json").write_text(json.dumps(cfg))
    cases.append(([str(other)], "is unreadable by this config: "))
    for argv, needle in cases:
        capsys.readouterr()
        assert cli.main(["eval", *argv]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: ") and needle in err and "\n" not in err, (argv, err)


@pytest.mark.timeout(120)
def test_existing_run_dir_is_refused_and_untouched(runs, capsys):
    before = _listing(runs["a"])
    assert cli.main(["train", *BASE, "--run-dir", str(runs["a"])]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "already exists" in err and "--resume" in err
    assert _listing(runs["a"]) == before


@pytest.mark.timeout(120)
@pytest.mark.parametrize(
    ("flags", "needle"),
    [(["--seed", "5"], "train.seed"), (["--agent.horizon", "4"], "agent.horizon"),
     (["--steps", "700"], "replay capacity")],
)  # fmt: skip
def test_resume_refuses_conflicting_overrides(runs, capsys, flags, needle):
    before = _listing(runs["b"])
    assert cli.main(["train", "--resume", str(runs["b"]), *flags]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and needle in err and len(err.splitlines()) == 1
    assert _listing(runs["b"]) == before


@pytest.mark.timeout(180)
def test_corrupt_checkpoint_names_the_file_and_deletes_nothing(runs, tmp_path, capsys):
    run = tmp_path / "copy"
    shutil.copytree(runs["b"], run)
    files = [p for p in (run / "checkpoints" / str(STEPS) / "state").rglob("*") if p.is_file()]
    victim = max(files, key=lambda p: p.stat().st_size)
    raw = bytearray(victim.read_bytes())
    raw[len(raw) // 2] ^= 0x55
    victim.write_bytes(bytes(raw))
    before = _listing(run)
    # Named by step, a damaged checkpoint is an error (without --resume-step, resume falls
    # back to an older one: tests/test_faults.py).
    argv = ["train", "--resume", str(run), "--resume-step", str(STEPS), "--no-progress"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert victim.name in err and "nothing was deleted" in err and "Traceback" not in err
    assert _listing(run) == before
