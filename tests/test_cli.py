"""The CLI shell: bad input, run-dir contents, Ctrl-C + resume == uninterrupted, failures.

The real runs use the smoke preset shrunk further (pendulum, 2 envs, 25 steps per env per
chunk, 650 env steps) and share one compiled train step through the compilation cache. The
failure paths (non-finite chunk, out of memory) use a toy `make_train` with a 3-float state.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest
from toys import ToyTrain, toy_argv

from sirl_jax.envs import load
from sirl_jax.run import cli, cost_probe, progress, runlog, runner
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
    return [{k: v for k, v in r.items() if k != "wall_time"} for r in runlog.read_jsonl(path)]


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


# ---------------------------------------------------------------- bad input, no training


@pytest.mark.timeout(60)
def test_unknown_task_lists_valid_tasks(tmp_path, capsys):
    assert cli.main(["train", "--task", "no-such-task", "--run-dir", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: unknown task 'no-such-task'") and "pendulum" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "r").exists()


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    ("flags", "needle"),
    [(["--steps", "-5"], "train.steps=-5"), (["--num-envs", "0"], "train.num_envs=0"),
     (["--utd", "0"], "train.utd"), (["--beta", "-1"], "beta"),
     (["--g", "best"], "g_source"), (["--model-size", "7M"], "model_size"),
     (["--steps", "many"], "--train.steps"), (["--keep", "0"], "--keep")],
)  # fmt: skip
def test_nonsense_numbers_give_one_line(tmp_path, capsys, flags, needle):
    assert cli.main(["train", *flags, "--run-dir", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and needle in err and len(err.splitlines()) == 1
    assert not (tmp_path / "r").exists()


@pytest.mark.timeout(120)
def test_buffer_that_does_not_fit_is_refused(tmp_path, capsys):
    huge = str(10**11)  # ~2.5 TB of replay
    argv = ["train", "--preset", "smoke", "--num-envs", "64", "--steps", huge, "--buffer-size",
            huge, "--run-dir", str(tmp_path / "r")]  # fmt: skip
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("error: replay buffer needs") and not (tmp_path / "r").exists()


@pytest.mark.timeout(60)
def test_help_runs_as_a_module():
    out = subprocess.run([sys.executable, "-m", "sirl_jax", "--help"], capture_output=True,
                         text=True, timeout=50, check=False)  # fmt: skip
    assert out.returncode == 0 and "train" in out.stdout and "tasks" in out.stdout


@pytest.mark.timeout(60)
def test_train_help_lists_nested_and_short_flags(capsys):
    assert cli.main(["train", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--agent.horizon" in out and "--train.num-envs" in out and "--g rmax|target" in out


def test_short_flags_expand_to_config_fields():
    argv = ["--seed", "3", "--num-envs=4", "--model-size", "1M", "--beta", "0.5", "--g",
            "target", "--no-save-buffer", "--agent.horizon", "5"]  # fmt: skip
    args, _ = cli.parse_train_args(argv)
    c = args.config
    assert (c.train.seed, c.train.num_envs, c.agent.model_size) == (3, 4, "1M")
    assert (c.agent.sirl.beta, c.agent.sirl.g_source, c.agent.horizon) == (0.5, "target", 5)
    assert c.train.save_buffer is False


def test_metric_mean_and_schedule():
    m = progress.MetricMean()
    m.add({"train/pi_loss": math.nan, "env/blowups": 0, "updates": 10, "episode/count": 1})
    m.add({"train/pi_loss": 2.0, "env/blowups": 1, "updates": 30, "episode/count": 2})
    m.add({"train/pi_loss": 4.0, "env/blowups": 0, "updates": 50, "episode/count": 0})
    assert m.pop() == {"train/pi_loss": 3.0, "env/blowups": 1, "updates": 50, "episode/count": 3}
    assert not m.pending()
    assert progress.crossed(90, 110, 100) and not progress.crossed(100, 199, 100)
    assert not progress.crossed(0, 10**9, 0)
    assert progress.failures({"nonfinite_loss": 2.0, "train/pi_loss": math.nan}) == [
        "nonfinite_loss=2"
    ]


def test_run_cost_by_hand():
    # 10k steps left, 2k of them random seed steps: 8k / 4 envs = 2000 vectorised acting steps
    # (2000 x 0.3 s) and 2000 x 4 x 0.5 + 2000 pretraining = 6000 updates (6000 x 0.1 s).
    run_cost_seconds = cost_probe.run_cost_seconds
    assert run_cost_seconds(10_000, 2_000, 4, 0.5, 2_000, 0.3, 0.1) == pytest.approx(600.0 + 600.0)
    assert run_cost_seconds(1_000, 2_000, 4, 0.5, 2_000, 0.3, 0.1) == pytest.approx(200.0)
    assert run_cost_seconds(0, 0, 1, 1.0, 0, 0.3, 0.1) == 0.0
    assert progress.format_duration(1.2e6) == "13.9 days"


@pytest.mark.timeout(300)
def test_cpu_run_of_a_gpu_sized_model_states_its_cost_first(tmp_path, capsys, monkeypatch):
    """A non-tiny model on CPU: one plan and one update are timed and the cost is printed
    before the first chunk (the loop itself is stubbed out: only the up-front line matters)."""
    monkeypatch.setattr(runner.Run, "loop", lambda self, state: None)
    argv = ["train", "--preset", "smoke", "--model-size", "1M", "--steps", "4000",
            "--num-envs", "2", "--no-progress", "--run-dir", str(tmp_path / "r")]  # fmt: skip
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    line = next(li for li in out.splitlines() if "of agent compute" in li)
    assert "for the 4,000 steps left (one plan call for 2 env(s)" in line, line
    assert "one update" in line and "use --preset smoke or a GPU" in line, line


# ---------------------------------------------------------------- failures (toy train)


def _toy_run(monkeypatch, tmp_path, toy: ToyTrain, *flags: str) -> int:
    monkeypatch.setattr(runner, "make_train", lambda config, env: toy)
    return cli.main(toy_argv(tmp_path / "run", *flags))


@pytest.mark.timeout(120)
def test_nonfinite_chunk_stops_and_saves_last_good_state(monkeypatch, tmp_path, capsys):
    toy = ToyTrain(fail_at=40)
    assert _toy_run(monkeypatch, tmp_path, toy) == 1
    err = capsys.readouterr().err.strip()
    assert "env step 40" in err and "nonfinite_loss=1" in err and "env step 30" in err
    ckpt = Checkpointer(tmp_path / "run" / "checkpoints")
    assert ckpt.steps() == [20, 30]  # the periodic one is kept, the last good one added
    abstract = jax.eval_shape(toy.init, jax.random.PRNGKey(0))
    good = ckpt.restore({"state": abstract.replace(buffer=None), "buffer": abstract.buffer})
    np.testing.assert_array_equal(good["state"].params, np.full(3, 3.0))  # 3 good chunks
    fresh = toy.init(jax.random.PRNGKey(0)).buffer["obs"]
    np.testing.assert_allclose(good["buffer"]["obs"], fresh + 3.0, rtol=1e-6)
    assert int(good["state"].env_steps) == 30 and int(good["state"].updates) == 3
    rows = runlog.read_jsonl(tmp_path / "run" / "metrics.jsonl")
    assert rows[-1]["env_steps"] == 40 and rows[-1]["nonfinite_loss"] == 1


@pytest.mark.timeout(120)
def test_nonfinite_without_guard_keeps_only_periodic_checkpoints(monkeypatch, tmp_path, capsys):
    assert _toy_run(monkeypatch, tmp_path, ToyTrain(fail_at=50), "--no-guard") == 1
    assert "not saved" in capsys.readouterr().err
    assert Checkpointer(tmp_path / "run" / "checkpoints").steps() == [20, 40]


@pytest.mark.timeout(120)
def test_out_of_memory_says_what_to_reduce(monkeypatch, tmp_path, capsys):
    assert _toy_run(monkeypatch, tmp_path, ToyTrain(fail_at=10**6, oom=True)) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: out of device memory") and "--buffer-size" in err
    assert "Traceback" not in err


def test_runlog_csv_grows_columns_and_drops_rows_past_a_step(tmp_path):
    log = runlog.RunLog(tmp_path, tensorboard=False)
    log.log("metrics", 10, {"a": 1.0})
    log.log("metrics", 20, {"a": 2.0, "b": math.nan})
    log.log("metrics", 30, {"a": 3.0, "b": 4.0})
    lines = (tmp_path / "metrics.csv").read_text().splitlines()
    assert lines[0].split(",") == ["env_steps", "wall_time", "a", "b"]
    assert [ln.split(",")[0] for ln in lines[1:]] == ["10", "20", "30"]
    assert lines[1].endswith(",1.0,")  # the column added later is empty in older rows
    log.drop_after(20)
    assert [r["env_steps"] for r in runlog.read_jsonl(tmp_path / "metrics.jsonl")] == [10, 20]
    assert len((tmp_path / "metrics.csv").read_text().splitlines()) == 3
    log.close()


@pytest.mark.timeout(300)
def test_smoke_preset_is_sized_for_a_playground_task(capsys):
    """`--task dmc:CartpoleSwingup --preset smoke` (T = 1000) was refused: the smoke buffer of
    4,000 entries cannot hold an episode per env. The preset is now sized for the task, and a
    flag given by hand still wins over a derived value."""
    pytest.importorskip("mujoco_playground")
    args, derived = cli.parse_train_args(["--task", "dmc:CartpoleSwingup", "--preset", "smoke"])
    need = 2 * 4 * 1001
    assert derived["train.buffer_size"] == (4_000, need) and derived["train.steps"] == (4_000, need)
    args.config.validate_for_task(1000)
    args, derived = cli.parse_train_args(
        ["--task", "dmc:CartpoleSwingup", "--preset", "smoke", "--steps", "20000"]
    )
    assert args.config.train.steps == 20_000 and "train.steps" not in derived
