"""The plain facts of a `report` page (`Report`), shared by `report` (which gathers them) and
`report_html` (which writes them), and the data-URI encoding of its media."""

from __future__ import annotations

import base64
from dataclasses import dataclass, field
from pathlib import Path

VIDEO_LIMIT = 64 << 20
"""Videos larger than this (bytes) are named, not embedded."""
POLICIES = (("planner", "planner (MPPI)"), ("policy", "policy prior"))


@dataclass
class Report:
    """The facts of one run, as the page shows them (plain Python values)."""

    run_dir: Path
    task: str
    seed: int
    task_line: str  # the task's id, episode length and success bar, from the registry
    config: dict  # flattened: "train.steps" -> value
    checkpoints: list[int]
    env_steps: int  # the last logged env step
    eval_source: str
    eval_rows: list[dict]  # one per env step: env_steps, episodes, eval/<policy>_<stat>
    random_return: float | None
    r_max_last: float
    r_max_best: float
    counters: dict[str, float]  # blow-ups, overflows, non-finite counts over the whole run
    cost: str
    starts: list[dict] = field(default_factory=list)  # versions.json entries
    plot_png: bytes | None = None
    notes: list[str] = field(default_factory=list)  # collapses, missing references/evals
    video: Path | None = None
    videos: list[Path] = field(default_factory=list)  # training videos (videos/step_*.mp4)
    best: dict | None = None  # the checkpoint marked best at evaluation (`read_best`)


def data_uri(mime: str, payload: bytes) -> str:
    """`data:<mime>;base64,...` of the bytes."""
    return f"data:{mime};base64,{base64.b64encode(payload).decode('ascii')}"
