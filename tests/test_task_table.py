"""The 31-task table (experiments/fidelity/task_table.py) reads the bars as issue 29 sets them:
a bar class under 99%, a reward stage over p95 0.02, a speed share under 0.30 each name the
task's miss; robot-floor never does; a task the harness did not reach says so."""

from __future__ import annotations

from experiments.fidelity.task_table import (
    cull,
    main_table,
    miss_table,
    reward_worst,
    speed,
    task_rows,
)


def _contact(agreement, bar, ours=0, hb=0, **extra):
    return {"agreement": agreement, "bar": bar, "ours_fires": ours, "hb_fires": hb, **extra}


def _row(tid, contacts, reward=(1e-8, 1e-7), stages=None):
    return {
        "task": tid,
        "states": 500,
        "contacts": contacts,
        "reward": {"median": reward[0], "p95": reward[1]},
        "stages": stages or {},
    }


def _line(lines, short):
    return next(x for x in lines if x.startswith(f"| {short} |"))


def test_the_31_tasks_in_order():
    rows = task_rows()
    assert len(rows) == 31 and rows[0][0] == "stand"
    assert ("highbar_hard", "h1strong-highbar_hard-v0") in rows


def test_bars():
    ids = dict(task_rows())
    parity = {
        ids["walk"]: _row(ids["walk"], {"robot-floor": _contact(0.5, False, 100, 300)}),
        ids["maze"]: _row(ids["maze"], {"robot-obstacle": _contact(0.95, True, 10, 20)},
                          stages={"0": {"median": 1e-3, "p95": 0.03}}),  # fmt: skip
        ids["push"]: _row(ids["push"], {"robot-fixture": _contact(0.995, True, 3, 3),
                                        "hand-object": _contact(None, True)}),  # fmt: skip
    }
    bench = {"rows": [
        {"label": "bare", "ratio": 1.0},
        {"label": "walk", "task": "walk", "ratio": 0.8},
        {"label": "push", "task": "push", "ratio": 0.25},
        {"label": "push budget -1", "task": "push", "max_contact_points": -1, "ratio": 0.1},
    ]}  # fmt: skip
    ratios = speed(bench)
    assert ratios == {"walk": 0.8, "push": 0.25}
    rerun = {"rows": [{"label": "push", "task": "push", "ratio": 0.4},
                      {"label": "push k32", "task": "push", "max_geom_pairs": 32, "ratio": 0.3},
                      {"label": "cube prism12", "task": "cube", "prism_sides": 12, "ratio": 0.9}]}
    assert speed(bench, rerun) == {"walk": 0.8, "push": 0.4}  # the later run's push
    assert speed(rerun, bench) == {"walk": 0.8, "push": 0.25}
    drops = cull({ids["push"]: {"groups": {"capsule-box": {"dropped_states": 0.04},
                                           "box-box": {"dropped_states": 0.24}}}})  # fmt: skip
    assert drops == {ids["push"]: "24.0"}
    lines = main_table(parity, ratios, drops)
    assert _line(lines, "walk").endswith("| all met |")  # robot-floor at 50%: no bar
    assert _line(lines, "maze").endswith("| robot-obstacle, reward |")
    assert reward_worst(parity[ids["maze"]]) == (1e-3, 0.03)
    assert _line(lines, "push").endswith("| 24.0 | speed |")
    assert "**0.25**" in _line(lines, "push")
    assert "not measured" in _line(lines, "kitchen")


def test_misses_list_only_bar_classes_under_99():
    ids = dict(task_rows())
    parity = {ids["hurdle"]: _row(ids["hurdle"], {
        "robot-obstacle": _contact(0.9, True, 40, 60, ours_only_states=10, hb_only_states=40,
                                   ours_only_depth_mm={"p50": 1.0, "p95": 2.0, "max": 3.0},
                                   hb_only_depth_mm={"p50": 4.0, "p95": 5.0, "max": 6.0},
                                   hb_only_our_gap_mm={"p50": 7.0, "p95": 8.0, "max": 9.0},
                                   hb_only_no_pair=2, ours_only_pairs=["a|b: 10"],
                                   hb_only_pairs=["c|d: 40"]),
        "robot-floor": _contact(0.5, False, 1, 2),
    })}  # fmt: skip
    lines = miss_table(parity)
    assert len(lines) == 3  # header, rule, hurdle's robot-obstacle
    assert lines[2] == (
        "| hurdle | robot-obstacle | 90.0% | 10, 1 / 3 | 40, 4 / 6 | 7 / 9; 2 "
        "| a\\|b: 10; c\\|d: 40 |"
    )
