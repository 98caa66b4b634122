"""`report SWEEP_DIR`: the sweep's page, arms as mean ± std over seeds, from hand-written run
directories (no training; the trained sweep's page is in test_sweep_cli.py)."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest

from sirl_jax.config import config_to_dict
from sirl_jax.presets import get_preset
from sirl_jax.run import cli, runlog
from sirl_jax.run.checkpoint import CHECKSUMS
from sirl_jax.run.errors import UsageError
from sirl_jax.run.report_sweep import gather_sweep, sweep_html

STEPS = (100, 200, 300, 400)
RETURNS = {  # pendulum's success bar is 150
    "beta=0_seed=0": (10.0, 20.0, 30.0, 40.0),
    "beta=0_seed=1": (0.0, 50.0, 10.0, 20.0),
    "beta=1_seed=0": (100.0, 160.0, 140.0, 200.0),
    "beta=1_seed=1": (150.0, 120.0, 130.0, 180.0),
}


def _write_sweep(root: Path, evals: bool = True) -> Path:
    sweep = root / "sweep"
    base = get_preset("smoke")
    for i, (name, returns) in enumerate(RETURNS.items()):
        run = sweep / name
        (run / "checkpoints" / "400").mkdir(parents=True)
        (run / "checkpoints" / "400" / CHECKSUMS).write_text("{}")
        agent = dataclasses.replace(base.agent, sirl=dataclasses.replace(
            base.agent.sirl, beta=float(i // 2)))  # fmt: skip
        cfg = dataclasses.replace(base, agent=agent,
                                  train=dataclasses.replace(base.train, seed=i % 2))
        (run / "config.json").write_text(json.dumps(config_to_dict(cfg)))
        metrics = [{"env_steps": s, "wall_time": s / 10.0, "env/blowups": float(s == 200)}
                   for s in STEPS]  # fmt: skip
        (run / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in metrics))
        runlog.CsvLog(run / "metrics.csv").extend(metrics)
        rows = [{"env_steps": s, "eval/policy_return": r, "eval/policy_return_std": 1.0}
                for s, r in zip(STEPS, returns, strict=True) if evals or i]  # fmt: skip
        (run / "eval.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
        runlog.CsvLog(run / "eval.csv").extend(rows)
    (sweep / "sweep.json").write_text(json.dumps(
        {"seeds": 2, "axes": {"sirl.beta": [0.0, 1.0]}, "runs": list(RETURNS)}))  # fmt: skip
    return sweep


def test_arms_are_the_runs_less_their_seed_with_each_runs_figures(tmp_path):
    r = gather_sweep(_write_sweep(tmp_path), curves=False)
    assert list(r.arms) == ["beta=0", "beta=1"] and r.success_bar == 150.0
    assert r.which == "policy" and r.seeds == 2
    zero, one = r.arms["beta=0"], r.arms["beta=1"]
    assert [x.seed for x in zero] == [0, 1]
    assert [x.final for x in zero] == [40.0, 20.0] and [x.final for x in one] == [200.0, 180.0]
    assert [x.last3 for x in one] == pytest.approx([500 / 3, 430 / 3])
    assert [(x.best, x.best_step) for x in zero] == [(40.0, 400), (50.0, 200)]
    # the first evaluation at or over the bar: 160 at 200; 150 (== the bar) at 100; never
    assert [x.first_at_bar for x in one] == [200, 100]
    assert [x.first_at_bar for x in zero] == [None, None]
    assert all(x.blowups == 1.0 for x in zero + one)
    # one program: 400 env steps per run in 40 s of wall time; 4 runs
    assert "4 runs in one program: 400 env steps per run in 40 s" in r.cost
    assert "10 s per run (40.0 env steps/s over the runs); on unknown device" in r.cost


def test_the_page_shows_each_arm_as_mean_and_std_over_seeds(tmp_path):
    page = sweep_html(gather_sweep(_write_sweep(tmp_path), curves=False))
    arm = lambda label: re.search(rf"<td class=l>{label}</td>(.*?)</tr>", page).group(1)
    # beta=0: finals 40, 20 -> 30.0 ± 10.0; last three 30, 26.7 -> 28.3 ± 1.7; best 40, 50
    assert "<td>30.0 ± 10.0</td><td>28.3 ± 1.7</td><td>45.0 ± 5.0</td><td>0 of 2</td>" in arm(
        "beta=0")  # fmt: skip
    assert "<td>190.0 ± 10.0</td>" in arm("beta=1") and "2 of 2, first @ 100" in arm("beta=1")
    assert "<code>beta=1_seed=1</code>" in page
    assert not re.search(r"""(src|href)=["']?https?:""", page)


def test_the_command_writes_the_sweep_page_and_refuses_an_unevaluated_run(tmp_path, capsys):
    sweep = _write_sweep(tmp_path)
    assert cli.main(["report", str(sweep)]) == 0
    page = (sweep / "report.html").read_text()
    assert "sweep of 4 runs" in page and 'alt="curves" src="data:image/png;base64,' in page
    bad = _write_sweep(tmp_path / "b", evals=False)
    with pytest.raises(UsageError, match="beta=0_seed=0 has no evaluations yet"):
        gather_sweep(bad, curves=False)
    assert cli.main(["report", str(bad)]) == 2
    assert "has no evaluations yet" in capsys.readouterr().err
    assert not (bad / "report.html").exists()
