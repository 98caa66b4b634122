"""`report`: the facts read from a run directory, a self-contained page, one-line bad input,
and (slow) the page drawn by headless Chromium. The real-run case is in test_cli.py."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from sirl_jax.config import config_to_dict
from sirl_jax.presets import get_preset
from sirl_jax.run import cli, report, runlog
from sirl_jax.run.checkpoint import CHECKSUMS

STEPS = (100, 200, 300, 400)


def _jsonl(path: Path, rows: list[dict]) -> None:
    """A log stream as `RunLog` writes it: JSONL and the CSV next to it."""
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    runlog.CsvLog(path.with_suffix(".csv")).extend(rows)


def _write_run(root: Path, checkpoint: bool = True, metrics: bool = True) -> Path:
    """A run dir as `train` leaves it: two starts (wall time restarts), 4 logged chunks, two
    evaluations, one checkpoint, a video."""
    run = root / "run"
    (run / "videos").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps(config_to_dict(get_preset("smoke"))))
    starts = [{"started": "2026-01-01T00:00:00+00:00", "git_commit": "abc", "backend": "cpu",
               "devices": ["cpu:0 cpu"], "jax": "0.7"}] * 2  # fmt: skip
    (run / "versions.json").write_text(json.dumps(starts))
    if metrics:
        _jsonl(run / "metrics.jsonl", [
            {"env_steps": s, "wall_time": w, "r_max": r, "env/blowups": b, "nonfinite_loss": 0.0}
            for s, w, r, b in zip(STEPS, (10.0, 20.0, 5.0, 15.0), (1.0, 3.0, 2.0, 4.0),
                                  (0.0, 2.0, 0.0, 1.0), strict=True)])  # fmt: skip
    rows = [{"env_steps": s, "wall_time": 1.0, "eval/planner_return": 10.0 * s,
             "eval/planner_return_std": 1.5, "eval/planner_length": 200.0,
             "eval/planner_success": 0.5, "eval/policy_return": 5.0 * s,
             "eval/policy_return_std": 2.0, "eval/policy_length": 200.0,
             "eval/policy_success": 0.0, "eval/planner_blowups": 1.0} for s in (200, 400)]
    _jsonl(run / "eval.jsonl", rows)
    if checkpoint:
        (run / "checkpoints" / "400").mkdir(parents=True)
        (run / "checkpoints" / "400" / CHECKSUMS).write_text("{}")
        (run / "checkpoints" / "200.orbax-checkpoint-tmp-1").mkdir()  # unfinished: not listed
    (run / "videos" / "400-planner.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42 fake video")
    return run


def test_facts_are_read_from_the_run_dir(tmp_path):
    run = _write_run(tmp_path)
    facts = report.gather(run, curves=False)
    assert facts.task == "pendulum" and facts.checkpoints == [400] and facts.env_steps == 400
    assert [r["env_steps"] for r in facts.eval_rows] == [200, 400]
    assert facts.eval_source.startswith("training")
    assert (facts.r_max_last, facts.r_max_best) == (4.0, 4.0)
    assert facts.counters["env blow-ups (training steps reset)"] == 3.0
    assert facts.counters["eval episodes cut by a blow-up (planner)"] == 2.0
    assert facts.counters["nonfinite_loss"] == 0.0
    # two processes: 20 s then 15 s of wall time; 400 steps / 35 s
    assert "35 s of wall time over 2 start(s), 11.4 env steps/s, on cpu:0" in facts.cost
    assert facts.video == run / "videos" / "400-planner.mp4"


def test_eval_command_rows_win_and_the_last_of_a_step_counts(tmp_path):
    run = _write_run(tmp_path)
    (run / "eval").mkdir()
    (run / "eval" / "checkpoints.csv").write_text(
        "env_steps,episodes,task,eval/policy_return,eval/policy_success\n"
        "400,10,pendulum,1.0,0.1\n400,10,pendulum,2.0,0.2\n")  # fmt: skip
    rows, source = report.eval_rows(run)
    assert source.startswith("`eval`") and len(rows) == 1
    assert rows[0]["eval/policy_return"] == 2.0 and rows[0]["task"] == "pendulum"


@pytest.mark.timeout(120)
def test_page_is_self_contained(tmp_path):
    run = _write_run(tmp_path)
    out = report.write_report(run, tmp_path / "page" / "r.html")
    page = out.read_text()
    refs = re.findall(r'(?:src|href)="([^"]*)"', page)
    assert refs and all(r.startswith("data:") for r in refs), refs
    assert "data:image/png;base64," in page and "data:video/mp4;base64," in page
    assert "4,000.0 ± 1.5" in page and "2,000.0 ± 2.0" in page  # planner and prior at 400
    assert "R_max" in page and "no reference curve for pendulum" in page
    assert "<script" not in page and "http" not in page.replace("http-equiv", "")


@pytest.mark.parametrize(("kind", "needle"), [
    ("missing", "does not exist"), ("no-config", "has no config.json"),
    ("no-metrics", "has no training logs"), ("no-checkpoint", "has no complete checkpoint"),
])  # fmt: skip
def test_bad_run_dirs_get_one_line(tmp_path, capsys, kind, needle):
    run = tmp_path / "nothing"
    if kind != "missing":
        run = _write_run(tmp_path, checkpoint=kind != "no-checkpoint",
                         metrics=kind != "no-metrics")  # fmt: skip
    if kind == "no-config":
        (run / "config.json").unlink()
    assert cli.main(["report", str(run)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and needle in err and "\n" not in err, err
    assert "report needs a run directory written by `train`" in err
    assert not (run / "report.html").exists()


def chromium() -> str | None:
    """A headless Chromium binary on PATH (Debian: chromium, or chromium-headless-shell)."""
    for name in ("chromium", "chromium-headless-shell", "chromium-browser", "google-chrome"):
        if path := shutil.which(name):
            return path
    return None


def screenshot(page: Path, png: Path, width: int = 1280, height: int = 2200) -> None:
    """Draws `page` with headless Chromium into `png` (offline: no network is needed)."""
    binary = chromium()
    cmd = [binary, "--headless", "--disable-gpu", "--no-sandbox", "--hide-scrollbars",
           "--mute-audio", f"--window-size={width},{height}", f"--screenshot={png}",
           page.resolve().as_uri()]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0 and png.is_file(), proc.stderr[-2000:]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_page_draws_in_headless_chromium(tmp_path):
    if chromium() is None:
        pytest.skip("no chromium binary (Debian: apt-get install chromium)")
    import numpy as np
    from PIL import Image

    run = _write_run(tmp_path)
    png = tmp_path / "shot.png"
    screenshot(report.write_report(run), png, 1000, 1600)
    image = np.asarray(Image.open(png).convert("RGB"))
    assert image.shape == (1600, 1000, 3)
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50  # text, table and plot drawn
