"""`train --seeds 2 --sweep sirl.beta=0,1`: four runs in one program, each a run directory the
other commands take; Ctrl-C + --resume equals the uninterrupted sweep; one run equals the
same run trained alone.

The runs are the fasttd3-smoke preset (pendulum, 4 envs): 1,400 env steps per run, the first
episodes finish at 1,000, so the last two chunks of 200 hold updates.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_cli import _load_final, _rows, _same, train_interrupted

from sirl_jax.run import cli, runlog

STEPS, STOP_AT = 1400, 800
BASE = ["--preset", "fasttd3-smoke", "--steps", str(STEPS), "--eval-every", "700",
        "--log-every", "200", "--checkpoint-every", "0", "--no-progress",
        "--no-tensorboard"]  # fmt: skip
SWEEP = ["--seeds", "2", "--sweep", "sirl.beta=0,1"]
NAMES = ["beta=0_seed=0", "beta=0_seed=1", "beta=1_seed=0", "beta=1_seed=1"]


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """A: the sweep uninterrupted. B: Ctrl-C after the chunk ending at STOP_AT, then --resume."""
    root = tmp_path_factory.mktemp("sweeps")
    a, b = root / "a", root / "b"
    assert cli.main(["train", *BASE, *SWEEP, "--run-dir", str(a)]) == 0
    stopped, sent = train_interrupted([*BASE, *SWEEP, "--run-dir", str(b)], STOP_AT)
    resumed = cli.main(["train", "--resume", str(b), "--no-progress", "--no-tensorboard"])
    return {"a": a, "b": b, "codes": (stopped, resumed), "sent": sent}


@pytest.mark.timeout(900)
def test_every_run_has_its_own_run_directory(sweeps):
    a = sweeps["a"]
    assert sweeps["codes"] == (0, 0)
    sweep = json.loads((a / "sweep.json").read_text())
    assert sweep == {"seeds": 2, "axes": {"sirl.beta": [0.0, 1.0]}, "runs": NAMES,
                     "first_seed": 0, "split": 0}  # fmt: skip
    for name, (beta, seed) in zip(NAMES, [(0, 0), (0, 1), (1, 0), (1, 1)], strict=True):
        config = runlog.load_config(a / name)
        assert (config.agent.sirl.beta, config.train.seed) == (beta, seed)
        evals = _rows(a / name / "eval.jsonl")
        assert [r["env_steps"] for r in evals] == [800, 1400]  # the chunks crossing 700, 1400
        assert all(math.isfinite(r["eval/policy_return"]) for r in evals)
    assert _rows(a / NAMES[0] / "metrics.jsonl")[-1]["updates"] > 0
    # beta changed what was learned: the two arms of seed 0 end apart
    ret = [_rows(a / n / "eval.jsonl")[-1]["eval/policy_return"] for n in NAMES]
    assert ret[0] != ret[2]


@pytest.mark.timeout(900)
def test_ctrl_c_then_resume_equals_the_uninterrupted_sweep(sweeps):
    assert sweeps["sent"] == [STOP_AT]
    for name in NAMES:
        step_a, leaves_a = _load_final(sweeps["a"] / name)
        step_b, leaves_b = _load_final(sweeps["b"] / name)
        assert step_a == step_b == STEPS
        for x, y in zip(leaves_a, leaves_b, strict=True):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
        for stream in ("metrics.jsonl", "eval.jsonl"):
            rows_a = _rows(sweeps["a"] / name / stream)
            rows_b = _rows(sweeps["b"] / name / stream)
            assert [r["env_steps"] for r in rows_a] == [r["env_steps"] for r in rows_b]
            for ra, rb in zip(rows_a, rows_b, strict=True):
                assert all(_same(ra[k], rb[k]) for k in ra), (name, ra, rb)


@pytest.mark.slow  # one more training; make test has the same comparison in test_sweep.py
@pytest.mark.timeout(900)
def test_a_run_of_the_sweep_equals_the_run_trained_alone(sweeps, tmp_path):
    """Through the CLI: bit for bit until the first update (chunk 5); after it within the
    tolerance that tests/test_sweep.py measured for vmap's reordered sums."""
    c = tmp_path / "c"
    assert cli.main(["train", *BASE, "--beta", "1", "--seed", "1", "--run-dir", str(c)]) == 0
    swept = _rows(sweeps["a"] / "beta=1_seed=1" / "metrics.jsonl")
    alone = _rows(c / "metrics.jsonl")
    assert [r["env_steps"] for r in swept] == [r["env_steps"] for r in alone]
    for rs, ra in zip(swept, alone, strict=True):
        for k in ra:
            if rs["updates"] == 0:
                assert _same(rs[k], ra[k]), (k, rs, ra)
            elif isinstance(ra[k], float) and math.isfinite(ra[k]):
                assert rs[k] == pytest.approx(ra[k], rel=1e-4, abs=5e-4), (k, rs, ra)
    ev_s = _rows(sweeps["a"] / "beta=1_seed=1" / "eval.jsonl")
    ev_a = _rows(c / "eval.jsonl")
    assert [r["env_steps"] for r in ev_s] == [r["env_steps"] for r in ev_a]
    assert ev_s[0]["eval/policy_return"] == ev_a[0]["eval/policy_return"]  # before any update


@pytest.mark.timeout(900)
def test_the_commands_take_a_run_of_the_sweep_and_refuse_the_sweep(sweeps, tmp_path, capsys):
    a = sweeps["a"]
    assert cli.main(["eval", str(a / "beta=1_seed=0"), "--episodes", "1"]) == 0
    assert cli.main(["plot", str(a), "--out", str(tmp_path / "sweep.png")]) == 0
    assert (tmp_path / "sweep.png").stat().st_size > 10_000
    capsys.readouterr()
    assert cli.main(["eval", str(a), "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert f"{a} is a sweep of 4 runs, not one run; give one of them, e.g. {a / NAMES[0]}" in err
    # report of the sweep: its arms; the trained runs evaluated at 800 and 1,400 env steps
    assert cli.main(["report", str(a), "--out", str(tmp_path / "sweep.html")]) == 0
    page = (tmp_path / "sweep.html").read_text()
    assert "sweep of 4 runs" in page and "<td class=l>beta=1</td><td>2</td>" in page
    assert cli.main(["report", str(a / NAMES[3]), "--out", str(tmp_path / "report")]) == 0


@pytest.mark.parametrize("flags, message", [
    (["--sweep", "batch_size=32,64"], "--sweep batch_size cannot be swept: it is static"),
    (["--seeds", "2", "--devices", "2"], "--devices 2 cannot be combined with a sweep"),
    (["--seeds", "0"], "--seeds 0 is invalid; allowed: an int >= 1"),
    (["--sweep", "sirl.beta=-1,1"], "--sweep sirl.beta=-1: "),
])  # fmt: skip
def test_a_sweep_that_cannot_run_is_refused_before_any_work(flags, message, tmp_path, capsys):
    run_dir = tmp_path / "r"
    assert cli.main(["train", *BASE, *flags, "--run-dir", str(run_dir)]) == 2
    assert message in capsys.readouterr().err
    assert not run_dir.exists()
