"""`plot`: runs grouped by config, mean ± std over seeds, collapse detection, a PNG written."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from sirl_jax.config import config_to_dict
from sirl_jax.presets import get_preset
from sirl_jax.run import plot


def _write_run(root: Path, name: str, seed: int, beta: float, steps, returns) -> Path:
    cfg = get_preset("smoke")
    cfg = dataclasses.replace(
        cfg, train=dataclasses.replace(cfg.train, seed=seed),
        agent=dataclasses.replace(cfg.agent, sirl=dataclasses.replace(cfg.agent.sirl, beta=beta)),
    )  # fmt: skip
    run = root / name
    run.mkdir()
    (run / "config.json").write_text(json.dumps(config_to_dict(cfg)))
    with open(run / "eval.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["env_steps", "wall_time", "eval/planner_return", "eval/policy_return"])
        for s, r in zip(steps, returns, strict=True):
            w.writerow([s, 1.0, r, r / 2])
    with open(run / "metrics.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["env_steps", "r_max", "episode/return"])
        for s, r in zip(steps, returns, strict=True):
            w.writerow([s, r + 10, ""])  # an empty cell: no episode ended in that chunk
    return run


def test_grouping_mean_std_and_collapse(tmp_path):
    a = _write_run(tmp_path, "a", 0, 1.0, [0, 1000, 2000], [10.0, 50.0, 90.0])
    b = _write_run(tmp_path, "b", 1, 1.0, [0, 1000, 2000, 3000], [20.0, 70.0, 30.0, 99.0])
    c = _write_run(tmp_path, "c", 0, 0.0, [0, 1000], [5.0, 6.0])
    runs = [plot.load_run(p) for p in (a, b, c)]
    groups = plot.group_runs(runs)
    assert [[r.path.name for r in g] for g in groups] == [["a", "b"], ["c"]]
    steps, mean, std = plot.mean_std(groups[0])
    np.testing.assert_array_equal(steps, [0, 1000, 2000])  # the steps both seeds evaluated
    np.testing.assert_allclose(mean, [15.0, 60.0, 60.0])
    np.testing.assert_allclose(std, [5.0, 10.0, 30.0])  # population std over the 2 seeds
    assert plot.find_collapse(runs[0].eval_steps, runs[0].eval_return) is None
    assert plot.find_collapse(runs[1].eval_steps, runs[1].eval_return) == (2000.0, 30.0, 70.0)
    assert plot.find_collapse(np.array([0, 1]), np.array([-5.0, -20.0])) is None  # best <= 0


@pytest.mark.timeout(120)
def test_png_is_written_and_collapses_are_reported(tmp_path, capsys):
    a = _write_run(tmp_path, "a", 0, 1.0, [0, 1000, 2000], [10.0, 50.0, 90.0])
    b = _write_run(tmp_path, "b", 1, 1.0, [0, 1000, 2000], [20.0, 70.0, 30.0])
    out = tmp_path / "fig" / "curves.png"
    warnings = plot.plot([a, b], out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
    assert len(warnings) == 1 and "env step 2,000 is below half its best 70.0" in warnings[0]
    assert warnings[0] in capsys.readouterr().out


def test_bad_run_dirs_are_named(tmp_path):
    with pytest.raises(plot.UsageError, match="does not exist"):
        plot.load_run(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "config.json").write_text(json.dumps(config_to_dict(get_preset("smoke"))))
    with pytest.raises(plot.UsageError, match="has no evaluations yet"):
        plot.load_run(tmp_path / "empty")
