"""`plot`: runs grouped by config, mean ± std over seeds, collapse detection, a PNG written, the
published reference curves."""

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


def _write_run(root: Path, name: str, seed: int, beta: float, steps, returns,
               task: str = "pendulum") -> Path:  # fmt: skip
    cfg = get_preset("smoke")
    cfg = dataclasses.replace(
        cfg, train=dataclasses.replace(cfg.train, seed=seed, task=task),
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


# The issue's table of the published curves (BMPC authors' data), eval return at 0 / 50k / 100k /
# 200k env steps, read off independently of the data file.
PUBLISHED = {
    ("TD-MPC2", "stand"): (16, 32, 41, 77), ("BMPC", "stand"): (17, 50, 262, 414),
    ("TD-MPC2", "sit_simple"): (9, 127, 309, 376), ("BMPC", "sit_simple"): (11, 111, 233, 440),
    ("TD-MPC2", "walk"): (4, 11, 22, 50), ("BMPC", "walk"): (4, 13, 30, 67),
    ("TD-MPC2", "reach"): (131, 450, 998, 1344), ("BMPC", "reach"): (-209, 186, 457, 1057),
}  # fmt: skip


def test_reference_curves_are_the_published_ones():
    from sirl_jax.envs.tasks import LOCOMOTION
    from sirl_jax.run import reference

    for row in LOCOMOTION:
        curves = reference.reference_curves(f"h1hand-{row.name}-v0")
        assert sorted(c.algo for c in curves) == ["BMPC", "TD-MPC2"], row.name
        for c in curves:
            assert c.steps[0] == 0 and c.steps[-1] >= 1_950_000 and np.all(np.diff(c.steps) > 0)
            assert np.all(c.lcb <= c.mean + 1e-9) and np.all(c.mean <= c.ucb + 1e-9), row.name
    for (algo, task), values in PUBLISHED.items():
        (curve,) = [c for c in reference.reference_curves(f"h1hand-{task}-v0") if c.algo == algo]
        got = [curve.at(s) for s in (0, 50_000, 100_000, 200_000)]
        np.testing.assert_allclose(got, values, atol=0.51, err_msg=f"{algo} {task}")
    assert reference.paper_2m()["sit_simple"]["TD-MPC2"] == [733.9, 255.79]
    assert reference.reference_curves("h1-stand-v0") == []
    assert "h1hand robot" in reference.missing_reason("h1-stand-v0")
    assert "14 locomotion tasks" in reference.missing_reason("h1hand-cube-v0")


@pytest.mark.timeout(120)
def test_reference_overlay_up_to_the_runs_last_step(tmp_path, capsys):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = _write_run(tmp_path, "sit", 0, 0.0, [0, 40_000, 70_000], [9.0, 60.0, 90.0],
                     task="sit_simple")  # an alias: the h1hand id's reference  # fmt: skip
    pend = _write_run(tmp_path, "pend", 0, 0.0, [0, 1000], [1.0, 2.0])
    fig, ax = plt.subplots()
    runs = [plot.load_run(run), plot.load_run(pend)]
    notes = plot._draw_references(ax, ["pendulum", "sit_simple"], runs)
    assert len(notes) == 1 and notes[0].startswith("note: no reference curve for pendulum")
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert set(lines) == {f"{a} reference, h1hand-sit_simple (published, 3 seeds)"
                          for a in ("TD-MPC2", "BMPC")}  # fmt: skip
    tdmpc2 = lines["TD-MPC2 reference, h1hand-sit_simple (published, 3 seeds)"]
    np.testing.assert_array_equal(tdmpc2.get_xdata(), [0, 50_000, 100_000])  # to 70k and past
    np.testing.assert_allclose(tdmpc2.get_ydata(), [8.85, 127.21, 308.59])
    plt.close(fig)
    out = tmp_path / "ref.png"
    from sirl_jax.run.cli import main

    assert main(["plot", str(run), str(pend), "--out", str(out), "--reference"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "note: no reference curve for pendulum" in capsys.readouterr().out
