"""The best checkpoint of a real (smoke) run: recorded at evaluation, kept past --keep, named
by the report, and what `eval`, `render` and `export` read with --best."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from sirl_jax.run import cli, runlog
from sirl_jax.run.args import EvalArgs, ExportArgs, RenderArgs, with_best
from sirl_jax.run.checkpoint import Checkpointer
from sirl_jax.run.errors import UsageError

STEPS, EVERY = 650, 100
ARGS = [
    "--preset", "smoke", "--steps", str(STEPS), "--seed-steps", "200", "--chunk-steps", "25",
    "--num-envs", "2", "--eval-every", str(EVERY), "--log-every", "50",
    "--checkpoint-every", "0", "--keep", "1", "--no-progress",
]  # fmt: skip


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("best") / "run"
    assert cli.main(["train", *ARGS, "--run-dir", str(run_dir)]) == 0
    evals = runlog.read_jsonl(run_dir / "eval.jsonl")
    returns = np.array([r["eval/planner_return"] for r in evals])
    best = int(np.argmax(returns))  # the first of equal maxima: a later tie is no better
    return {"dir": run_dir, "best": int(evals[best]["env_steps"]),
            "value": float(returns[best]), "steps": [int(r["env_steps"]) for r in evals]}


@pytest.mark.timeout(600)
def test_the_best_evaluation_is_recorded_and_kept_past_keep(run):
    assert run["steps"] == list(range(EVERY, STEPS, EVERY))
    record = json.loads((run["dir"] / "checkpoints" / "best.json").read_text())
    assert record["step"] == run["best"] and record["metric"] == "eval/planner_return"
    assert record["value"] == pytest.approx(run["value"], rel=1e-6)
    # --keep 1: the final checkpoint, and the best one besides.
    assert Checkpointer(run["dir"] / "checkpoints").steps() == sorted({run["best"], STEPS})


@pytest.mark.timeout(120)
def test_best_flag_names_that_checkpoint_and_refuses_what_it_cannot(run, tmp_path, capsys):
    d = str(run["dir"])
    for args in (EvalArgs(run=d, best=True), RenderArgs(run=d, best=True),
                 ExportArgs(run=d, best=True)):  # fmt: skip
        assert with_best(args).step == run["best"]
        assert f"env step {run['best']:,}" in capsys.readouterr().out
    assert with_best(EvalArgs(run=d, step=STEPS)).step == STEPS  # no --best: unchanged
    with pytest.raises(UsageError, match=f"--best and --step {STEPS} each name a checkpoint"):
        with_best(EvalArgs(run=d, step=STEPS, best=True))
    with pytest.raises(UsageError, match="--best needs a RUN_DIR"):
        with_best(RenderArgs(best=True, random=True, task="pendulum"))
    with pytest.raises(UsageError, match="records no best checkpoint"):
        with_best(EvalArgs(run=str(tmp_path), best=True))
    assert cli.main(["export", str(tmp_path), "--best"]) == 2  # one line, exit 2
    assert "records no best checkpoint" in capsys.readouterr().err


@pytest.mark.timeout(120)
def test_report_names_the_best_checkpoint(run, tmp_path):
    out = tmp_path / "report.html"
    assert cli.main(["report", str(run["dir"]), "--out", str(out)]) == 0
    page = out.read_text()
    assert f"{run['best']:,}</b><span>best checkpoint (eval/planner_return" in page


@pytest.mark.slow  # 1.5 min: the eval command's compile
@pytest.mark.timeout(300)
def test_eval_best_evaluates_the_best_checkpoint_as_training_did(run, capsys):
    """`eval --best` at the run's own eval size (1 episode) evaluates the best checkpoint with
    training's key: it reproduces the return logged there, the best of the run."""
    assert cli.main(["eval", str(run["dir"]), "--best", "--episodes", "1"]) == 0
    assert f"--best: the checkpoint at env step {run['best']:,}" in capsys.readouterr().out
    with open(run["dir"] / "eval" / "checkpoints.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    assert int(row["env_steps"]) == run["best"]
    assert float(row["eval/planner_return"]) == pytest.approx(run["value"], rel=1e-5)
