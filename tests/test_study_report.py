"""The sit_simple study's summary.json and figure from hand-written CSVs (no JAX)."""

from __future__ import annotations

import json

from experiments.studies.sit_simple_report import Args, main, summarize
from sirl_jax.run.runlog import CsvLog

FIELDS = ("seed", "env_steps", "wall_s", "planner_return", "planner_length", "policy_return",
          "policy_length", "r_max", "cpu_s")  # fmt: skip


def _arm(root, arm, finals, wall):
    d = root / "study" / arm
    d.mkdir(parents=True)
    rows = []
    for step in (0, 50_000, 100_000):
        for seed, final in enumerate(finals):
            ret = 10.0 + (final - 10.0) * step / 100_000  # a straight line from 10 to `final`
            rows.append({"seed": seed, "env_steps": step, "wall_s": wall * step / 100_000,
                         "planner_return": ret, "planner_length": 100.0, "policy_return": ret,
                         "policy_length": 100.0, "r_max": "" if step == 0 else 2 * ret,
                         "cpu_s": 1.0})  # fmt: skip
    CsvLog(d / "eval.csv").extend(rows)
    (d / "done.json").write_text(json.dumps({"wall_s": wall}))


def test_summary_has_the_promised_keys_and_values(tmp_path):
    _arm(tmp_path, "tdmpc2", [100.0, 120.0, 80.0], 5000.0)
    _arm(tmp_path, "tdmpbc", [150.0, 90.0, 110.0], 5200.0)
    (tmp_path / "random.json").write_text(json.dumps({"mean": 9.5, "episodes": 64}))
    s = summarize(tmp_path)
    assert set(s) == {"task", "env_steps_per_seed", "random_return", "reference_100k", "arms",
                      "wall_clock_s"}  # fmt: skip
    assert s["task"] == "h1hand-sit_simple-v0" and s["env_steps_per_seed"] == 100_000
    assert s["random_return"] == 9.5 and s["reference_100k"] == 308.6
    assert s["arms"]["tdmpc2"] == {"final": [100.0, 120.0, 80.0], "at_100k": [100.0, 120.0, 80.0]}
    assert s["arms"]["tdmpbc"]["final"] == [150.0, 90.0, 110.0]
    assert s["wall_clock_s"] == 5200.0  # the arms ran side by side: the longer one
    out = tmp_path / "out"
    main(Args(results=str(tmp_path), out=str(out)))
    assert json.loads((out / "summary.json").read_text()) == s
    assert (out / "figure.png").stat().st_size > 10_000
