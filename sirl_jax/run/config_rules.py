"""The shell's rules for the config a run starts with: what a resumed run may change
(`check_resume`, `RESUME_MUTABLE`) and sizing a CPU preset for a task (`fit_to_task`).

`cli.py` applies both before a run starts; the core config (`sirl_jax/config.py`) knows
neither.
"""

from __future__ import annotations

import dataclasses

from sirl_jax.config import Config, flatten_config

RESUME_MUTABLE = frozenset(
    {"train.steps", "train.eval_every", "train.eval_episodes", "train.checkpoint_every",
     "train.log_every", "train.save_buffer", "train.max_blowup_rate", "train.video_every"}
)  # fmt: skip
"""Config fields a resumed run may change; every other field must match the saved config."""


def check_resume(saved: Config, given: Config) -> None:
    """Raises ValueError unless `given` differs from `saved` only in `RESUME_MUTABLE` fields
    and keeps the replay capacity (the buffer's shape)."""
    old, new = flatten_config(saved), flatten_config(given)
    refused = [k for k in old if old[k] != new[k] and k not in RESUME_MUTABLE]
    if refused:
        detail = ", ".join(f"{k} (saved {old[k]!r}, given {new[k]!r})" for k in refused)
        allowed = ", ".join(sorted(RESUME_MUTABLE))
        raise ValueError(f"--resume cannot change {detail}; a resumed run may change {allowed}")
    if saved.train.capacity != given.train.capacity:
        raise ValueError(
            f"--resume: --steps {given.train.steps:,} would change the replay capacity "
            f"min(buffer_size, steps) from {saved.train.capacity:,} to "
            f"{given.train.capacity:,}; start a new run, or set a buffer_size <= steps "
            "when starting one you may extend"
        )


def fit_to_task(config: Config, episode_length: int) -> tuple[Config, dict[str, tuple]]:
    """A CPU preset sized for a task with episodes of `episode_length` (T) steps.

    Raises what depends on T, never lowers it: replay capacity (buffer_size and steps) to two
    episodes per env, 2 E (T + 1); explicit seed_steps to one episode per env, E T; eval_every
    to E T (an evaluation costs T steps). Returns the config and {field: (preset, derived)}
    for each value changed.
    """
    t, e = config.train, config.train.num_envs
    need = 2 * e * (episode_length + 1)
    derived = {
        "buffer_size": max(t.buffer_size, need),
        "steps": max(t.steps, need),
        "seed_steps": None if t.seed_steps is None else max(t.seed_steps, e * episode_length),
        "eval_every": max(t.eval_every, e * episode_length) if t.eval_every else 0,
    }
    changed = {k: (getattr(t, k), v) for k, v in derived.items() if getattr(t, k) != v}
    train = dataclasses.replace(t, **{k: v for k, (_, v) in changed.items()})
    return dataclasses.replace(config, train=train), {f"train.{k}": v for k, v in changed.items()}


__all__ = ["RESUME_MUTABLE", "check_resume", "fit_to_task"]
