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
    # the official TD-MPC2's curve joins the figure; the summary (our arms) is unchanged
    (tmp_path / "official").mkdir()
    CsvLog(tmp_path / "official" / "eval.csv").extend([
        {"seed": 0, "env_steps": step, "wall_s": 1.0, "planner_return": ret, "planner_length": "",
         "policy_return": "", "policy_length": "", "r_max": "", "cpu_s": 1.0}
        for step, ret in ((0, 9.0), (10_063, 40.0), (20_110, 80.0))])  # fmt: skip
    with_official = tmp_path / "out2"
    main(Args(results=str(tmp_path), out=str(with_official)))
    assert json.loads((with_official / "summary.json").read_text()) == s
    assert (with_official / "figure.png").read_bytes() != (out / "figure.png").read_bytes()


def _curve(d, returns, wall_step_s, cpu_step_s, planner: bool):
    """One seed per entry of `returns` (a list per seed, one eval every 10k steps)."""
    d.mkdir(parents=True)
    rows = []
    for seed, rets in enumerate(returns):
        for i, ret in enumerate(rets):
            rows.append({"seed": seed, "env_steps": 10_000 * i, "wall_s": wall_step_s * i,
                         "planner_return": ret if planner else "", "planner_length": "",
                         "policy_return": 0.0 if planner else ret, "policy_length": 100.0,
                         "r_max": "", "cpu_s": cpu_step_s * i})  # fmt: skip
    CsvLog(d / "eval.csv").extend(rows)


def test_parallel_learner_summary_times_each_seed_to_10x_random(tmp_path):
    from experiments.studies import parallel_learner as pl

    # 10x random = 100: the first evaluation at or over it counts, on each clock
    # (seed 2's step-0 evaluation, of the untrained actor, is over the bar and does not count)
    _curve(tmp_path / "pl" / "beta0", [[5, 50, 100, 90], [5, 120, 130, 140], [500, 10, 20, 30]],
           wall_step_s=360.0, cpu_step_s=720.0, planner=False)
    _curve(tmp_path / "pl" / "beta1", [[5, 99.9, 101, 150], [5, 200, 80, 300], [5, 5, 5, 100]],
           wall_step_s=720.0, cpu_step_s=1440.0, planner=False)
    _curve(tmp_path / "td", [[8, 20, 150], [50, 60, 70]], wall_step_s=1800.0, cpu_step_s=900.0,
           planner=True)
    (tmp_path / "random.json").write_text(json.dumps({"mean": 10.0, "episodes": 64}))
    s = pl.summarize(tmp_path / "pl", tmp_path / "td", tmp_path / "random.json")
    assert s["random_return"] == 10.0 and s["task"] == "h1hand-sit_simple-v0"
    assert s["arms"]["beta0"]["final"] == [90.0, 140.0, 30.0]
    assert s["arms"]["beta0"]["hours_to_10x"] == [0.2, 0.1, None]  # evals 2 and 1 x 360 s
    assert s["arms"]["beta0"]["cpu_hours_to_10x"] == [0.4, 0.2, None]
    assert s["arms"]["beta1"]["hours_to_10x"] == [0.4, 0.2, 0.6]  # 99.9 is under the bar
    assert s["tdmpc2_hours_to_10x"] == [1.0, None]  # the planner column, not the prior's
    assert s["tdmpc2_cpu_hours_to_10x"] == [0.5, None]
    out = tmp_path / "out"
    # the official FastTD3's log: tqdm's carriage returns, other lines, two evaluations
    log = tmp_path / "official.log"
    log.write_text("Using FastTD3\n 10%|#  | 300/6260\rEVAL env_steps=9600 return=12.5 "
                   "length=40.0 wall_s=100\nEvaluating at global step 600\n"
                   "EVAL env_steps=19200 return=30.25 length=61.5 wall_s=207\n")  # fmt: skip
    pl.main(pl.Args(results=str(tmp_path / "pl"), tdmpc2=str(tmp_path / "td"),
                     random=str(tmp_path / "random.json"), out=str(out), zero_action=None,
                     official_log=str(log)))  # fmt: skip
    assert json.loads((out / "summary.json").read_text()) == s
    assert (out / "figure.png").stat().st_size > 10_000
    rows = CsvLog(out / "official_fasttd3" / "eval.csv").rows()
    assert [(float(r["env_steps"]), float(r["return"]), float(r["length"])) for r in rows] == [
        (9600.0, 12.5, 40.0), (19200.0, 30.25, 61.5)]


def test_parallel_learner_config_is_the_fasttd3_cpu_preset_at_beta():
    import dataclasses

    from experiments.study import arm_config, study_of
    from sirl_jax.presets import get_preset

    preset = get_preset("fasttd3-cpu")
    for beta in (0.0, 1.0):
        cfg = arm_config(study_of("parallel_learner"), f"beta{beta:g}")
        assert cfg.agent.kind == "fasttd3" and cfg.agent.sirl.beta == beta
        # it ran before replay sampling was an option, FastTD3 drawing episode-uniformly
        assert cfg.agent.fasttd3.replay_sampling == "episode"
        assert preset.agent.fasttd3.replay_sampling == "transition"
        episode = dataclasses.replace(preset.agent.fasttd3, replay_sampling="episode")
        assert cfg.agent.fasttd3 == episode
        assert cfg.train.task == "h1hand-sit_simple-v0" and cfg.train.steps == 200_000
        assert (cfg.train.eval_every, cfg.train.eval_episodes) == (10_000, 4)
        assert cfg.train.num_envs == preset.train.num_envs


def test_the_figure_names_the_env_each_study_ran_on(tmp_path):
    """The 100k study's config.json (saved before the env options existed) reads as the reduced
    contacts it ran on; the 200k run's as HumanoidBench's; a folder without one gets no label."""
    from pathlib import Path

    from experiments.studies.sit_simple_report import env_label

    committed = Path(__file__).parent.parent / "docs/results/sit_simple_study"
    assert env_label(committed / "study" / "tdmpc2") == " (reduced contacts)"
    assert env_label(committed / "study200k" / "tdmpc2") == " (HumanoidBench's contacts)"
    assert env_label(tmp_path) == ""


def test_video_report_chooses_headless_gl_before_mujoco_is_imported(tmp_path):
    """`--video` renders with MuJoCo, which reads MUJOCO_GL once, at import; the figure's env
    label imports MuJoCo first, so the report must choose the backend before anything else.
    Run in a fresh interpreter (this one has MuJoCo imported already) with MUJOCO_GL unset; an
    import hook records MUJOCO_GL at MuJoCo's first import."""
    import os
    import subprocess
    import sys

    _arm(tmp_path, "tdmpc2", [100.0, 120.0, 80.0], 5000.0)
    _arm(tmp_path, "tdmpbc", [150.0, 90.0, 110.0], 5200.0)
    (tmp_path / "random.json").write_text(json.dumps({"mean": 9.5, "episodes": 64}))
    script = f"""
import importlib.abc, os, sys
seen = []
class Hook(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == "mujoco" and not seen:
            seen.append(os.environ.get("MUJOCO_GL"))
        return None
sys.meta_path.insert(0, Hook())
import experiments.studies.sit_simple_report as r
r.video = lambda *a: __import__("mujoco")  # the real one renders from a checkpoint
r.main(r.Args(results={str(tmp_path)!r}, out={str(tmp_path / "out")!r}, video=True))
print("MUJOCO_GL at import:", seen)
"""
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    done = subprocess.run([sys.executable, "-c", script], cwd=root, env=env, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    line = done.stdout.strip().splitlines()[-1]
    assert line in ("MUJOCO_GL at import: ['osmesa']", "MUJOCO_GL at import: ['egl']"), line


def test_solved_report_leaves_mujoco_unimported_until_main_chose_gl():
    """sit_simple_solved_report --with-video: MuJoCo reads MUJOCO_GL once, at import, so the
    module must not import it before `main` has chosen the headless backend."""
    import subprocess
    import sys
    from pathlib import Path

    script = ("import sys; import experiments.studies.sit_simple_solved_report; "
              "print('mujoco' in sys.modules)")  # fmt: skip
    done = subprocess.run([sys.executable, "-c", script], cwd=Path(__file__).parents[1],
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "False"


def test_the_paper_table_reads_each_task_and_arm_beside_the_papers_numbers(tmp_path):
    """paper_report's table from hand-written arms (the committed layout: a seed column):
    each arm's final planner return as mean and std over seeds, the paper's beside it."""
    from experiments.studies.paper_report import table
    from sirl_jax.run.reference import paper_2m

    for arm, finals in (("TDMPBC", [300.0, 500.0]), ("TD-MPC2", [100.0, 100.0])):
        (tmp_path / "paper_table_cpu" / "stand" / arm).mkdir(parents=True)
        CsvLog(tmp_path / "paper_table_cpu" / "stand" / arm / "eval.csv").extend([
            {"seed": s, "env_steps": step, "wall_s": 1.0, "cpu_s": 1.0, "planner_return": ret,
             "policy_return": "", "r_max": ""}
            for s, final in enumerate(finals) for step, ret in ((0, 5.0), (80_000, final))])
    rows = table("paper_table_cpu", ("stand",), tmp_path)
    by_arm = {r["arm"]: r for r in rows}
    assert (by_arm["TDMPBC"]["mean"], by_arm["TDMPBC"]["std"]) == (400.0, 100.0)
    assert (by_arm["TD-MPC2"]["mean"], by_arm["TD-MPC2"]["std"]) == (100.0, 0.0)
    assert by_arm["TDMPBC"]["task"] == "h1-stand-v0" and by_arm["TDMPBC"]["steps"] == 80_000
    paper = paper_2m()["stand"]
    assert by_arm["TD-MPC2"]["paper"] == f"{paper['TD-MPC2'][0]} ± {paper['TD-MPC2'][1]}"
    assert (tmp_path / "paper_table_cpu" / "paper_table_cpu.png").stat().st_size > 5_000
    assert (tmp_path / "paper_table_cpu" / "paper_table_cpu.csv").is_file()
