"""The top-level run configuration: `Config(agent, train)`, presets, and config round-trips.

Frozen dataclasses; tyro turns them into the CLI and each field docstring becomes its `--help`.
Derived values (seed steps, buffer capacity, updates per env step) are functions of the config
and the task, computed where used; nothing is written back.

Named presets are in `sirl_jax/presets.py`.

This module also owns the run directory's config contract: `config_to_dict` /
`config_from_dict` (config.json) and `flatten_config`. What a resumed run may change and how
a CPU preset is sized for a task are the shell's rules (`sirl_jax/run/config_rules.py`).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.agent.config import check as _check
from sirl_jax.hb_compat import (
    EXACT,
    HAND_FLOOR,
    HB,
    TASK_BUDGET,
    check_contact_budget,
    check_contact_set,
    check_hand_floor,
    check_hb_compat,
)


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """The training loop (spec tdmpc2.md §3.7, §4, §6). Steps count transitions over all envs."""

    task: str = "h1hand-walk-v0"
    """Task id or alias from the registry (`pendulum`, `h1hand-walk-v0`, ...), or a MuJoCo
    Playground env as `dmc:CartpoleSwingup` / `playground:Go1JoystickFlatTerrain` (needs the
    optional `playground` extra)."""
    impl: str = "jax"
    """MJX physics backend: "jax" (XLA, any device; the default, CPU and GPU) or "warp"
    (MJX-Warp on a CUDA GPU or the CPU; needs the `warp` extra). See docs/training.md."""
    hb_compat: str = EXACT
    """HumanoidBench's quirks: "exact" reproduces them, so returns compare with the paper and
    HumanoidBench's curves; "fixed" corrects them (docs/tasks.md, "HumanoidBench's quirks")."""
    contact_set: str = HB
    """What the manipulation scenes' colliders touch: "hb" (HumanoidBench's set: the robot
    against tables and shelves, objects against each other) or "reduced" (the cheaper cut set
    earlier runs used). docs/tasks.md, "Contact sets"."""
    hand_floor: str = HAND_FLOOR[0]
    """Which hand colliders touch the floor: "all" (HumanoidBench: all 62), "palms" (the wrist
    and palm boxes) or "none" (earlier runs: the hands pass through it). docs/tasks.md, "Hands on
    the floor"."""
    contact_budget: int = TASK_BUDGET
    """MJX-JAX's contact budget: the solver sees only the k most penetrating contacts. -1: the
    task's own (every locomotion task 64, bookshelf, kitchen, powerlift and room theirs; the
    other manipulation tasks none; docs/tasks.md, "Contact budget"); 0: none (every contact
    slot); k >= 1: k. A step that fills the budget is counted in `env/physics_overflow`."""
    seed: int = 0
    """PRNG seed of the run."""
    steps: int = 2_000_000
    """Total env steps (transitions summed over envs). 2M is where HumanoidBench's published
    TD-MPC2 curves stop."""
    num_envs: int = 1
    """E, environments stepped in parallel. 1 is the reference; each env's episodes are stored
    as their own episodes (the official `vectorized_env` branch)."""
    chunk_steps: int = 100
    """K, vectorised env steps per jitted call (one `lax.scan`); a call makes K * E transitions."""
    utd: float = 1.0
    """Updates per transition (TD-MPC2: 1). Each vectorised step owes E * utd updates; a
    fractional remainder is carried to the next step."""
    seed_steps: int | None = None
    """Random-action transitions before planning starts, summed over envs. None: max(1000, 5T)
    per env, i.e. max(1000, 5T) * E in total (the official vectorised branch), so every env has
    finished at least one episode before the first update. Rounded up to a multiple of E."""
    pretrain: bool = True
    """Run seed_steps * utd updates at once when the seed phase ends (the reference)."""
    buffer_size: int = 3_000_000
    """Replay capacity in transitions (HumanoidBench's fork: 3M; the official code: 1M); the
    buffer holds min(buffer_size, steps)."""
    eval_every: int = 50_000
    """Env steps between evaluations (0 = never); evaluated at the first chunk boundary past it."""
    eval_episodes: int = 1
    """Episodes per evaluation, run in parallel (HumanoidBench: 1; the official code: 10)."""
    checkpoint_every: int | None = None
    """Env steps between checkpoints; None: steps // 10 (about 10 per run, so `eval` over
    checkpoints can locate a collapse); 0: only at the end, on Ctrl-C/SIGTERM and on a
    non-finite chunk."""
    save_buffer: bool = True
    """Save the replay buffer with checkpoints (resuming without it destabilises, tdmpc2#28)."""
    log_every: int = 10_000
    """Env steps between log lines; metrics are aggregated over the chunks in between."""
    video_every: int = 0
    """Env steps between training videos (0 = none): one eval episode rendered into
    RUN/videos/step_<env steps>.mp4, TensorBoard and wandb (`sirl_jax/run/videos.py`)."""
    max_blowup_rate: float = 0.01
    """A physics blow-up (non-finite qpos, qvel, observation or reward) resets that env and
    drops its running episode; the run stops, with the last good state saved, only when a
    chunk's blow-ups exceed this fraction of its env steps. 0: stop at the first one."""

    def __post_init__(self) -> None:
        _check(bool(self.task), "train.task", self.task, "a non-empty task name")
        _check(self.impl in ("jax", "warp"), "train.impl", self.impl, "'jax' or 'warp'")
        check_hb_compat(self.hb_compat, "train.hb_compat")
        check_contact_set(self.contact_set, "train.contact_set")
        check_hand_floor(self.hand_floor, "train.hand_floor")
        check_contact_budget(self.contact_budget, "train.contact_budget")
        _check(self.seed >= 0, "train.seed", self.seed, "an int >= 0")
        _check(self.steps >= 1, "train.steps", self.steps, "an int >= 1")
        _check(self.num_envs >= 1, "train.num_envs", self.num_envs, "an int >= 1")
        _check(self.chunk_steps >= 1, "train.chunk_steps", self.chunk_steps, "an int >= 1")
        _check(
            math.isfinite(self.utd) and 0 < self.utd <= 64,
            "train.utd",
            self.utd,
            "a float in (0, 64]",
        )
        _check(
            self.seed_steps is None or self.seed_steps >= 1,
            "train.seed_steps",
            self.seed_steps,
            "None (= max(1000, 5T) * num_envs) or an int >= 1",
        )
        _check(self.buffer_size >= 1, "train.buffer_size", self.buffer_size, "an int >= 1")
        _check(self.eval_every >= 0, "train.eval_every", self.eval_every, "an int >= 0")
        _check(self.video_every >= 0, "train.video_every", self.video_every, "an int >= 0")
        _check(self.eval_episodes >= 1, "train.eval_episodes", self.eval_episodes, "an int >= 1")
        _check(
            self.checkpoint_every is None or self.checkpoint_every >= 0,
            "train.checkpoint_every",
            self.checkpoint_every,
            "None (= steps // 10) or an int >= 0",
        )
        _check(self.log_every >= 1, "train.log_every", self.log_every, "an int >= 1")
        _check(
            0.0 <= self.max_blowup_rate <= 1.0,
            "train.max_blowup_rate",
            self.max_blowup_rate,
            "a float in [0, 1]",
        )

    @property
    def env_options(self) -> dict[str, Any]:
        """The options that shape the task's env (`sirl_jax.envs.load`'s keywords)."""
        return {
            "hb_compat": self.hb_compat,
            "contact_set": self.contact_set,
            "hand_floor": self.hand_floor,
            "contact_budget": self.contact_budget,
        }

    @property
    def steps_per_call(self) -> int:
        """Transitions made by one jitted train step: K * E."""
        return self.chunk_steps * self.num_envs

    @property
    def checkpoint_interval(self) -> int:
        """Env steps between checkpoints (0 = none but the final one): steps // 10 if unset."""
        if self.checkpoint_every is None:
            return max(self.steps // 10, 1)
        return self.checkpoint_every

    @property
    def capacity(self) -> int:
        """Replay capacity in transitions: min(buffer_size, steps)."""
        return min(self.buffer_size, self.steps)

    def resolved_seed_steps(self, episode_length: int) -> int:
        """Seed transitions (summed over envs) for a task with episodes of `episode_length`.

        None resolves to max(1000, 5T) per env (spec §3.7) times E (official vectorised
        branch). The result is rounded up to a multiple of E, since envs step together.
        """
        if episode_length < 1:
            raise ValueError(f"episode_length={episode_length!r} is invalid; allowed: >= 1")
        e = self.num_envs
        raw = self.seed_steps if self.seed_steps is not None else max(1000, 5 * episode_length) * e
        return -(-raw // e) * e

    def pretrain_updates(self, episode_length: int) -> int:
        """Updates run at once when the seed phase ends: seed_steps * utd (0 if not pretrain)."""
        if not self.pretrain:
            return 0
        return max(1, round(self.resolved_seed_steps(episode_length) * self.utd))


@dataclasses.dataclass(frozen=True)
class Config:
    """A whole run: the agent (TD-MPC2 + the self-imitative term) and the training loop."""

    agent: AgentConfig = dataclasses.field(default_factory=AgentConfig)
    train: TrainConfig = dataclasses.field(default_factory=TrainConfig)

    def __post_init__(self) -> None:
        _check(
            self.train.capacity >= self.agent.window + 1,
            "train.buffer_size",
            self.train.buffer_size,
            f">= horizon + 1 ({self.agent.window + 1}) transitions (n-step + 1 under fasttd3)",
        )

    def validate_for_task(self, episode_length: int) -> None:
        """Checks that need the task: episode length vs horizon and vs the replay capacity.

        (Whether the task has the success bar `g_source="target"` needs is `make_agent`'s.)
        """
        _check(
            episode_length > self.agent.window + 1,
            "episode_length",
            episode_length,
            f"> horizon + 1 ({self.agent.window + 1}) for task {self.train.task!r}",
        )
        ring = self.train.capacity // self.train.num_envs
        _check(
            ring >= episode_length + 1,
            "train.buffer_size",
            self.train.buffer_size,
            f"a capacity (min(buffer_size, steps)) of at least num_envs * (episode_length + 1)"
            f" = {self.train.num_envs * (episode_length + 1)} so a whole episode fits per env",
        )


def config_to_dict(config: Any) -> dict:
    """A nested config dataclass as plain JSON-able dicts (what config.json holds)."""
    return dataclasses.asdict(config)


def config_from_dict(cls: type, data: dict, where: str = "config") -> Any:
    """Rebuilds a (nested, frozen) config dataclass from `config_to_dict` output.

    Raises ValueError naming the fields this version does not know (a run written by other
    code); fields missing from `data` take their defaults.
    """
    hints = typing.get_type_hints(cls)
    unknown = sorted(set(data) - {f.name for f in dataclasses.fields(cls)})
    if unknown:
        raise ValueError(f"{where}: unknown fields {unknown} (written by another version?)")
    kwargs = {}
    for name, value in data.items():
        hint = hints[name]
        if dataclasses.is_dataclass(hint) and isinstance(value, dict):
            value = config_from_dict(hint, value, f"{where}.{name}")
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return cls(**kwargs)


def flatten_config(config: Any) -> dict[str, Any]:
    """{'train.steps': 1000, 'agent.sirl.beta': 1.0, ...} of a nested config dataclass."""
    out = {}

    def walk(prefix: str, obj: Any) -> None:
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if dataclasses.is_dataclass(value):
                walk(f"{prefix}{f.name}.", value)
            else:
                out[prefix + f.name] = value

    walk("", config)
    return out


__all__ = [
    "AgentConfig",
    "Config",
    "SirlConfig",
    "TrainConfig",
    "config_from_dict",
    "config_to_dict",
    "flatten_config",
]
