"""Videos while training (`--train.video-every N`): one eval episode every N env steps.

Each goes to RUN/videos/step_<env steps, 9 digits>.mp4 (the run's policy in eval mode: the
planner where the agent plans, else the actor; the evaluation's key), to TensorBoard as an
animated GIF under `eval/video` (every 4th frame at half size, in the Images tab; TensorBoard's
own video panel needs moviepy), and to wandb as a video when `--wandb` is on. `report` shows
them in order. A line gives each video's render time, which is not training time.

MuJoCo reads its GL backend once, at import, so `prepare_gl` runs before anything imports it:
a machine without a headless GL library gets one warning, and the run trains without videos.
A render that fails later is warned about once, and the run goes on without videos.
"""

from __future__ import annotations

import io
import json
import time
from pathlib import Path
from typing import Any

_GL_PROBLEM: list[str] = []  # why videos are off on this machine, once `prepare_gl` found it


def wants_video(argv: list[str], flag_value) -> bool:
    """Whether `train` argv asks for videos: --train.video-every N > 0, or a resumed run's
    saved config with it (read as JSON: nothing imported)."""
    given = flag_value(argv, "--train.video-every") or flag_value(argv, "--video-every")
    if given is not None:
        return given.strip() not in ("0", "")
    resume = flag_value(argv, "--resume")
    path = Path(resume) / "config.json" if resume else None
    if path is None or not path.is_file():
        return False
    try:
        return int(json.loads(path.read_text())["train"].get("video_every", 0)) > 0
    except (ValueError, KeyError, TypeError):
        return False


def prepare_gl() -> None:
    """Chooses the headless GL backend (`render.select_gl`) before MuJoCo is imported; a
    missing library is kept as the reason videos are off."""
    from sirl_jax.run.errors import UsageError
    from sirl_jax.run.render import select_gl

    try:
        select_gl()
    except UsageError as e:
        _GL_PROBLEM.append(str(e))


class TrainingVideos:
    """Renders one eval episode when the run crosses a multiple of `train.video_every`."""

    def __init__(self, config, train, run_dir: Path, log, write, eval_key):
        self.config, self.train, self.dir, self.log, self.write = config, train, run_dir, log, write
        self.eval_key = eval_key  # `runner.eval_key`: the evaluation's key at an env step
        self.every = config.train.video_every
        self.off = _GL_PROBLEM[0] if _GL_PROBLEM else None
        if self.every and self.off:
            write(f"warning: --train.video-every {self.every}: {self.off}; training goes on "
                  "without videos")  # fmt: skip

    def maybe(self, state, before: int, env_steps: int) -> Path | None:
        from sirl_jax.run.progress import crossed

        if not self.every or self.off or not crossed(before, env_steps, self.every):
            return None
        try:
            return self.render(state, env_steps)
        except Exception as e:  # a renderer failure never stops training
            self.off = f"{type(e).__name__}: {str(e).strip().splitlines()[0][:200]}"
            self.write(f"warning: the video at env step {env_steps:,} failed ({self.off}); "
                       "training goes on without videos")  # fmt: skip
            return None

    def render(self, state, env_steps: int) -> Path:
        from sirl_jax.run.render import render_policy

        t0 = time.perf_counter()
        plans = self.config.agent.plans
        out = self.dir / "videos" / f"step_{env_steps:09d}.mp4"
        summary = render_policy(self.train.env, self.train.agent, state.agent,
                                "planner" if plans else "prior", 1,
                                self.eval_key(self.config.train.seed, env_steps), out,
                                f"{self.config.train.task} @ {env_steps:,} env steps",
                                width=320, height=240)  # fmt: skip
        seconds = time.perf_counter() - t0
        self._publish(out, env_steps)
        self.write(f"video @ {env_steps:,}: {out.relative_to(self.dir)}, {summary['frames']} "
                   f"frames, return {summary['returns'][0]:.4g}; rendered in {seconds:.1f} s "
                   "(not training time)")  # fmt: skip
        return out

    def _publish(self, mp4: Path, env_steps: int) -> None:
        tb, wandb_run = self.log.writers()
        if tb is not None:
            tb.file_writer.add_summary(gif_summary("eval/video", mp4), env_steps)
            tb.flush()
        if wandb_run is not None:
            import wandb

            wandb_run.log({"eval/video": wandb.Video(str(mp4), format="mp4")}, step=env_steps)


def gif_summary(tag: str, mp4: Path, every: int = 4) -> Any:
    """A TensorBoard image summary holding `mp4` as an animated GIF (every `every`-th frame,
    half size), as tensorboardX's add_video writes one."""
    import imageio.v2 as imageio
    import numpy as np
    from tensorboardX.proto.summary_pb2 import Summary

    reader = imageio.get_reader(mp4)
    fps = reader.get_meta_data().get("fps", 50)
    frames = [np.asarray(f)[::2, ::2] for i, f in enumerate(reader) if i % every == 0]
    reader.close()
    buf = io.BytesIO()
    imageio.mimsave(buf, frames, format="GIF", duration=1000 * every / fps, loop=0)
    h, w = frames[0].shape[:2]
    image = Summary.Image(height=h, width=w, colorspace=3, encoded_image_string=buf.getvalue())
    return Summary(value=[Summary.Value(tag=tag, image=image)])
