"""Named configs: `get_preset(name)`; `PRESETS` refuses a duplicate name.

  default        the reference: TD-MPC2 5M + TDMPBC (beta 1, G = R_max), HumanoidBench's settings.
  tdmpbc-paper   the TDMPBC paper's runs: default with the HumanoidBench fork's 2023 policy
                 log-prob (`entropy_form="v1"`), the one setting where the fork differs.
  smoke          a CPU-sized run on the pendulum swing-up: `AgentConfig.tiny` (batch 32), 4 envs,
                 a few thousand steps.
  cpu            a CPU-sized learning run on the pendulum swing-up: `AgentConfig.small`, 8 envs,
                 UTD 0.25 (docs/training.md).
  gpu            the reference agent on h1hand-walk for one GPU, one seed of the paper's setting
                 (1 env, UTD 1); S seeds are vmapped by the caller (docs/training.md).
  gpu-fast       gpu with 16 envs per seed and UTD 1/16 (one update per vectorised step), as
                 the official TD-MPC2 vectorised branch runs: a deviation from the paper.
  fasttd3-smoke  FastTD3 + SIRL (`agent.kind="fasttd3"`) on the pendulum with small networks.
  fasttd3-cpu    FastTD3 + SIRL sized for a 2-core CPU on h1hand-sit_simple: 32 envs, batch
                 1024, critic 512 / actor 256 wide (FastTD3's: 128 envs, 32768, 1024 / 512).
  fasttd3-gpu    FastTD3 + SIRL at FastTD3's HumanoidBench settings with 1024 envs (its own
                 runs use 128 CPU-simulated envs), replay 2048 transitions per env.

The CPU presets fit any task (`fits_task`): the shell applies `fit_to_task`
(`sirl_jax/run/config_rules.py`) to them, which raises their episode-length-dependent sizes
(replay capacity, seed steps, eval cadence) for tasks with longer episodes than the pendulum's.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping

from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.agent.fasttd3_config import FastTD3Config
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
    # through jax.vmap over Train.init/step keys (sirl_jax/sweep.py).
    return Config(
        agent=AgentConfig(),
        train=TrainConfig(task="h1hand-walk-v0", impl="jax", chunk_steps=500, eval_episodes=10),
    )


def _gpu_fast() -> Config:
    base = _gpu()
    train = dataclasses.replace(base.train, num_envs=16, utd=1 / 16, chunk_steps=100)
    return dataclasses.replace(base, train=train)


def _fasttd3(**fields) -> AgentConfig:
    """FastTD3 + the self-imitative term (beta 1, G = R_max), BC by squared error."""
    return AgentConfig(kind="fasttd3", fasttd3=FastTD3Config(**fields),
                       sirl=SirlConfig(bc_form="mse_mean"))  # fmt: skip


def _fasttd3_smoke() -> Config:
    return Config(
        agent=_fasttd3(actor_hidden_dim=32, critic_hidden_dim=64, num_atoms=21, batch_size=64,
                       v_min=-100.0, v_max=100.0),
        train=dataclasses.replace(_smoke().train, seed_steps=400),
    )  # fmt: skip


def _fasttd3_cpu() -> Config:
    return Config(
        agent=_fasttd3(actor_hidden_dim=256, critic_hidden_dim=512, batch_size=1024),
        train=TrainConfig(task="h1hand-sit_simple-v0", steps=1_000_000, num_envs=32,
                          chunk_steps=50, seed_steps=320, buffer_size=1_000_000,
                          eval_every=20_000, eval_episodes=8, log_every=10_000),
    )  # fmt: skip


def _fasttd3_gpu() -> Config:
    return Config(
        agent=_fasttd3(),
        train=TrainConfig(task="h1hand-sit_simple-v0", steps=20_000_000, num_envs=1024,
                          chunk_steps=100, seed_steps=10 * 1024, buffer_size=2048 * 1024,
                          eval_every=500_000, eval_episodes=16, log_every=100_000),
    )  # fmt: skip


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

register_preset(
    "fasttd3-smoke", _fasttd3_smoke, "FastTD3 + SIRL smoke run: small nets, pendulum, 4 envs",
    fits_task=True,
)
register_preset(
    "fasttd3-cpu", _fasttd3_cpu,
    "FastTD3 + SIRL on a CPU: 32 envs, batch 1024, critic 512 / actor 256, h1hand-sit_simple",
)
register_preset(
    "fasttd3-gpu", _fasttd3_gpu,
    "FastTD3 + SIRL on one GPU: its HumanoidBench sizes (batch 32768, critic 1024 / actor 512), "
    "1024 envs",
)

CPU_LEARNS: dict[str, tuple[str, str, str]] = {
    "h1hand-sit_simple-v0": (
        "fasttd3-cpu",
        "--train.hand-floor none --train.contact-set reduced --train.contact-budget 0",
        "past HumanoidBench's bar of 750 on 3 of 3 seeds, first after 0.17-0.45 h of "
        "training CPU on 2 cores (docs/results/sit_simple_solved.md, on that env)",
    ),
}
"""Task id -> (preset, the env flags it was measured with, what it reached): the presets
measured to learn a task on a CPU. A CPU run's cost line names the one for its task."""

__all__ = ["CPU_LEARNS", "PRESETS", "Preset", "get_preset", "register_preset"]
