"""The CLI without a real run: bad input in one line, help and short flags, the cost line, the
failure paths (a non-finite chunk, out of memory) on a toy `make_train` with a 3-float state,
the CSV log, and a preset sized for a Playground task."""

from __future__ import annotations

import math
import subprocess
import sys

import jax
import numpy as np
import pytest
from toys import ToyTrain, toy_argv

from sirl_jax.run import cli, cost_probe, progress, runlog, runner
from sirl_jax.run.checkpoint import Checkpointer

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
    assert "one update" in line and "use a GPU, or a smaller model (--preset smoke)" in line


def test_the_cpu_hint_names_the_preset_that_learns_the_task():
    import dataclasses

    from sirl_jax.presets import get_preset

    reference = dataclasses.replace(get_preset("default"), train=dataclasses.replace(
        get_preset("default").train, task="sit_simple"))  # fmt: skip
    hint = cost_probe.cpu_hint(reference)
    assert ("on a CPU use the fasttd3-cpu preset, measured past HumanoidBench's bar of 750"
            in hint)  # fmt: skip
    assert hint.endswith("python -m sirl_jax train --task h1hand-sit_simple-v0 --preset "
                         "fasttd3-cpu --train.hand-floor none --train.contact-set reduced "
                         "--train.contact-budget 0")  # fmt: skip
    assert cost_probe.cpu_hint(get_preset("fasttd3-cpu")).startswith(
        "; fasttd3-cpu learns this task on a CPU: past")  # fmt: skip
    walk = dataclasses.replace(reference, train=dataclasses.replace(reference.train, task="walk"))
    assert "no preset is measured to learn this task on a CPU" in cost_probe.cpu_hint(walk)


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
