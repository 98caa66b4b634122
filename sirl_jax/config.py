"""The top-level run configuration: `Config(agent, train)` and named presets.

Frozen dataclasses; tyro turns them into the CLI and each field docstring becomes its `--help`.
Derived values (seed steps, buffer capacity, updates per env step) are functions of the config
and the task, computed where used; nothing is written back.

Presets live in `PRESETS`, which refuses a duplicate name:
  default  the reference: TD-MPC2 5M + TDMPBC (beta 1, G = R_max), HumanoidBench's settings.
  smoke    a CPU-sized run on the pendulum swing-up: tiny model, 4 envs, a few thousand steps.
  cpu      a CPU-sized learning run on the pendulum swing-up (experiments/learning_check.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator, Mapping

from sirl_jax.agent.config import AgentConfig, SirlConfig


def _check(ok: bool, name: str, value: object, allowed: str) -> None:
    if not ok:
        raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}")


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """The training loop (spec tdmpc2.md §3.7, §4, §6). Steps count transitions over all envs."""

    task: str = "h1hand-walk-v0"
    """Task id or alias from the registry (`pendulum`, `h1hand-walk-v0`, ...), or a MuJoCo
    Playground env as `dmc:CartpoleSwingup` / `playground:Go1JoystickFlatTerrain` (needs the
    optional `playground` extra)."""
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
    checkpoint_every: int = 100_000
    """Env steps between checkpoints (0 = only at the end, on Ctrl-C/SIGTERM and on a
    non-finite chunk). 100k: a 2M-step run loses at most 5% of its work to a crash."""
    save_buffer: bool = True
    """Save the replay buffer with checkpoints (resuming without it destabilises, tdmpc2#28)."""
    log_every: int = 10_000
    """Env steps between log lines; metrics are aggregated over the chunks in between."""

    def __post_init__(self) -> None:
        _check(bool(self.task), "train.task", self.task, "a non-empty task name")
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
        _check(self.eval_episodes >= 1, "train.eval_episodes", self.eval_episodes, "an int >= 1")
        _check(
            self.checkpoint_every >= 0,
            "train.checkpoint_every",
            self.checkpoint_every,
            "an int >= 0",
        )
        _check(self.log_every >= 1, "train.log_every", self.log_every, "an int >= 1")

    @property
    def steps_per_call(self) -> int:
        """Transitions made by one jitted train step: K * E."""
        return self.chunk_steps * self.num_envs

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
            self.train.capacity >= self.agent.horizon + 1,
            "train.buffer_size",
            self.train.buffer_size,
            f">= horizon + 1 ({self.agent.horizon + 1}) transitions",
        )

    def validate_for_task(self, episode_length: int, success_bar: float | None) -> None:
        """Checks that need the task: episode length vs horizon, and a success bar for G."""
        _check(
            episode_length > self.agent.horizon + 1,
            "episode_length",
            episode_length,
            f"> horizon + 1 ({self.agent.horizon + 1}) for task {self.train.task!r}",
        )
        ring = self.train.capacity // self.train.num_envs
        _check(
            ring >= episode_length + 1,
            "train.buffer_size",
            self.train.buffer_size,
            f"a capacity (min(buffer_size, steps)) of at least num_envs * (episode_length + 1)"
            f" = {self.train.num_envs * (episode_length + 1)} so a whole episode fits per env",
        )
        if self.agent.sirl.enabled and self.agent.sirl.g_source == "target":
            _check(
                success_bar is not None,
                "agent.sirl.g_source",
                "target",
                f"'rmax', since task {self.train.task!r} has no success bar",
            )


class _Presets(Mapping[str, Callable[[], Config]]):
    def __init__(self) -> None:
        self._factories: dict[str, Callable[[], Config]] = {}
        self._docs: dict[str, str] = {}

    def register(self, name: str, factory: Callable[[], Config], doc: str = "") -> None:
        if name in self._factories:
            raise ValueError(f"preset {name!r} is already registered")
        self._factories[name] = factory
        self._docs[name] = doc

    def __getitem__(self, name: str) -> Callable[[], Config]:
        if name not in self._factories:
            raise KeyError(f"unknown preset {name!r}; valid presets: {', '.join(sorted(self))}")
        return self._factories[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._factories)

    def __len__(self) -> int:
        return len(self._factories)

    def doc(self, name: str) -> str:
        self[name]
        return self._docs[name]


PRESETS = _Presets()
"""Named configs; `get_preset(name)` builds one. Registering a taken name raises ValueError."""


def register_preset(name: str, factory: Callable[[], Config], doc: str = "") -> None:
    """Adds a named preset (a zero-argument factory returning a `Config`)."""
    PRESETS.register(name, factory, doc)


def get_preset(name: str) -> Config:
    """The `Config` of a named preset; a clear error lists the valid names."""
    return PRESETS[name]()


def _smoke() -> Config:
    return Config(
        agent=AgentConfig.tiny(batch_size=32),
        train=TrainConfig(
            task="pendulum",
            steps=4_000,
            num_envs=4,
            chunk_steps=50,
            seed_steps=1_000,
            buffer_size=4_000,
            eval_every=2_000,
            log_every=1_000,
        ),
    )


def _cpu() -> Config:
    return Config(
        agent=AgentConfig(
            model_size="tiny",
            latent_dim=64,
            mlp_dim=128,
            enc_dim=64,
            num_q=2,
            num_samples=64,
            num_elites=8,
            num_pi_trajs=8,
            iterations=2,
            batch_size=64,
        ),
        train=TrainConfig(
            task="pendulum",
            steps=30_000,
            num_envs=8,
            chunk_steps=50,
            utd=0.25,
            buffer_size=30_000,
            eval_every=2_000,
            eval_episodes=8,
            log_every=2_000,
        ),
    )


register_preset("default", Config, "the reference: TD-MPC2 5M + TDMPBC, HumanoidBench settings")
register_preset("smoke", _smoke, "CPU smoke run: tiny model, pendulum, 4 envs, 4k steps")
register_preset("cpu", _cpu, "CPU learning run: small model, pendulum, 8 envs, UTD 0.25")

__all__ = [
    "PRESETS",
    "AgentConfig",
    "Config",
    "SirlConfig",
    "TrainConfig",
    "get_preset",
    "register_preset",
]
