"""--train.video-every: videos while training, in the run dir, TensorBoard and the report; a
machine without GL gets one warning and trains on."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
RUN = ["-m", "sirl_jax", "train", "--preset", "fasttd3-smoke", "--steps", "1200",
       "--eval-every", "600", "--video-every", "600", "--no-progress"]  # fmt: skip


def _train(run_dir: Path, env: dict) -> subprocess.CompletedProcess:
    # a fresh process: MuJoCo reads MUJOCO_GL once, at import
    return subprocess.run([sys.executable, *RUN, "--run-dir", str(run_dir)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=840)  # fmt: skip


def _images(tb: Path, tag: str) -> list[tuple[int, bytes]]:
    """(step, encoded image) of every image summary `tag` in the event files (TFRecords of
    Event protos: length u64, its crc u32, the proto, its crc u32)."""
    import struct

    from tensorboardX.proto.event_pb2 import Event

    out = []
    for path in sorted(tb.glob("events.out.tfevents.*")):
        raw, i = path.read_bytes(), 0
        while i < len(raw):
            (n,) = struct.unpack("<Q", raw[i : i + 8])
            event = Event.FromString(raw[i + 12 : i + 12 + n])
            i += 16 + n
            out += [(event.step, v.image.encoded_image_string) for v in event.summary.value
                    if v.tag == tag]  # fmt: skip
    return out


@pytest.mark.slow  # 56 s cold: a training process rendering two videos
@pytest.mark.timeout(900)
def test_videos_go_to_the_run_dir_tensorboard_and_the_report(tmp_path):
    from sirl_jax.run.report import write_report

    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    done = _train(tmp_path / "run", env)
    assert done.returncode == 0, done.stderr[-3000:]
    videos = sorted((tmp_path / "run" / "videos").glob("*.mp4"))
    assert [v.name for v in videos] == ["step_000000600.mp4", "step_000001200.mp4"]
    assert all(v.stat().st_size > 1_000 for v in videos)
    lines = [x for x in (done.stdout + done.stderr).splitlines() if x.startswith("video @")]
    assert len(lines) == 2 and "rendered in" in lines[0] and "(not training time)" in lines[0]
    gifs = _images(tmp_path / "run" / "tb", "eval/video")
    assert [step for step, _ in gifs] == [600, 1200]
    assert all(gif[:6] == b"GIF89a" for _, gif in gifs)
    page = write_report(tmp_path / "run").read_text()
    assert "Training videos (2)" in page
    assert page.index("env step 600:") < page.index("env step 1,200:")


@pytest.mark.timeout(900)
def test_without_gl_one_warning_and_training_goes_on(tmp_path):
    """No headless GL library (ctypes finds none, as on a machine without libOSMesa or libEGL):
    one warning, no videos, the run trains to the end."""
    script = ("import ctypes.util, sys; ctypes.util.find_library = lambda name: None; "
              "from sirl_jax.run.cli import main; sys.exit(main(sys.argv[1:]))")  # fmt: skip
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    done = subprocess.run([sys.executable, "-c", script, *RUN[2:], "--run-dir",
                           str(tmp_path / "run")], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=840)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    out = done.stdout + done.stderr
    warnings = [x for x in out.splitlines() if "--train.video-every 600" in x]
    assert len(warnings) == 1 and warnings[0].startswith("warning:"), out[-2000:]
    assert "needs libOSMesa" in warnings[0] and "training goes on without videos" in warnings[0]
    assert not (tmp_path / "run" / "videos").exists()
    assert "done at env step 1,200" in out
