"""Named configs: `get_preset(name)`; `PRESETS` refuses a duplicate name.

  default        the reference: TD-MPC2 5M + TDMPBC (beta 1, G = R_max), HumanoidBench's settings.
  tdmpbc-paper   the TDMPBC paper's runs: default with the HumanoidBench fork's 2023 policy
                 log-prob (`entropy_form="v1"`), the one setting where the fork differs.
  smoke          a CPU-sized run on the pendulum swing-up: `AgentConfig.tiny` (batch 32), 4 envs,
                 a few thousand steps.
  cpu            a CPU-sized learning run on the pendulum swing-up: `AgentConfig.small`, 8 envs,
                 UTD 0.25 (experiments/studies/learning_check.py).
  gpu            the reference agent on h1hand-walk for one GPU, one seed of the paper's setting
                 (1 env, UTD 1); S seeds are vmapped by the caller (docs/training.md).
  gpu-fast       gpu with 16 envs per seed and UTD 1/16 (one update per vectorised step), as
                 the official TD-MPC2 vectorised branch runs: a deviation from the paper.

The CPU presets fit any task (`fits_task`): the shell applies `fit_to_task`
(`sirl_jax/run/config_rules.py`) to them, which raises their episode-length-dependent sizes
(replay capacity, seed steps, eval cadence) for tasks with longer episodes than the pendulum's.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping

from sirl_jax.agent.config import AgentConfig
from sirl_jax.config import Config, TrainConfig


@dataclasses.dataclass(frozen=True)
class Preset:
    """A named config: `factory()` builds it; `fits_task`: `fit_to_task` applies to it."""

    factory: Callable[[], Config]
    doc: str = ""
    fits_task: bool = False


class _Presets(Mapping[str, Preset]):
    def __init__(self) -> None:
        self._presets: dict[str, Preset] = {}

    def register(self, name: str, preset: Preset) -> None:
        if name in self._presets:
            raise ValueError(f"preset {name!r} is already registered")
        self._presets[name] = preset

    def __getitem__(self, name: str) -> Preset:
        if name not in self._presets:
            raise KeyError(f"unknown preset {name!r}; valid presets: {', '.join(sorted(self))}")
        return self._presets[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._presets)

    def __len__(self) -> int:
        return len(self._presets)


PRESETS = _Presets()
"""Named configs; `get_preset(name)` builds one. Registering a taken name raises ValueError."""


def register_preset(
    name: str, factory: Callable[[], Config], doc: str = "", fits_task: bool = False
) -> None:
    """Adds a named preset (a zero-argument factory returning a `Config`)."""
    PRESETS.register(name, Preset(factory, doc, fits_task))


def get_preset(name: str) -> Config:
    """The `Config` of a named preset; a clear error lists the valid names."""
    return PRESETS[name].factory()


def _tdmpbc_paper() -> Config:
    return Config(agent=AgentConfig(entropy_form="v1"))


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
        agent=AgentConfig.small(),
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


def _gpu() -> Config:
    # One seed of the paper's setting. Config has no seed axis: S seeds run as one program
    # through jax.vmap over Train.init/step keys (experiments/paper/common.py run_arm).
    return Config(
        agent=AgentConfig(),
        train=TrainConfig(task="h1hand-walk-v0", impl="jax", chunk_steps=500, eval_episodes=10),
    )


def _gpu_fast() -> Config:
    base = _gpu()
    train = dataclasses.replace(base.train, num_envs=16, utd=1 / 16, chunk_steps=100)
    return dataclasses.replace(base, train=train)


register_preset("default", Config, "the reference: TD-MPC2 5M + TDMPBC, HumanoidBench settings")
register_preset(
    "tdmpbc-paper", _tdmpbc_paper, "the paper's runs: default + the HB fork's v1 policy log-prob"
)
register_preset(
    "smoke", _smoke, "CPU smoke run: tiny model, pendulum, 4 envs, 4k steps", fits_task=True
)
register_preset(
    "cpu", _cpu, "CPU learning run: small model, pendulum, 8 envs, UTD 0.25", fits_task=True
)
register_preset("gpu", _gpu, "one GPU seed of the paper's setting: 5M, 512 x 8 MPPI, 1 env, UTD 1")
register_preset(
    "gpu-fast", _gpu_fast, "gpu with 16 envs per seed, UTD 1/16 (deviation: not the paper's)"
)

__all__ = ["PRESETS", "Preset", "get_preset", "register_preset"]
