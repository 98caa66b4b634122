"""Agent configuration: TD-MPC2 defaults (spec §1-§3) plus the self-imitative term (spec §5).

Frozen dataclasses; nothing here is mutated at run time. Architecture fields default to None and
are resolved from `model_size` by `AgentConfig.arch`; explicit values override the preset.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple


class ModelArch(NamedTuple):
    """Resolved network widths."""

    enc_dim: int
    mlp_dim: int
    latent_dim: int
    num_enc_layers: int
    num_q: int


# TD-MPC2 `common/__init__.py` presets (spec §1.6). "tiny" is NOT a reference size: tests/CPU only.
MODEL_PRESETS: dict[str, ModelArch] = {
    "1M": ModelArch(256, 384, 128, 2, 2),
    "5M": ModelArch(256, 512, 512, 2, 5),
    "19M": ModelArch(1024, 1024, 768, 3, 5),
    "48M": ModelArch(1792, 1792, 768, 4, 5),
    "317M": ModelArch(4096, 4096, 1376, 5, 8),
    "tiny": ModelArch(32, 32, 32, 2, 5),
}

BC_FORMS = ("loglik", "mse_sample", "mse_mean")
G_SOURCES = ("rmax", "target")
RETURN_KINDS = ("undiscounted", "discounted")
ENTROPY_FORMS = ("scaled", "v1")


def _choice(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not allowed; choose one of {allowed}")


def _check(ok: bool, name: str, value: object, allowed: str) -> None:
    if not ok:
        raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}")


@dataclasses.dataclass(frozen=True)
class SirlConfig:
    """The self-imitative BC term of TDMPBC (spec §5)."""

    enabled: bool = True
    """False: the plain TD-MPC2 policy update (no BC term computed at all)."""
    beta: float = 1.0
    """omega(R) = beta * exp(min((R - G) / max(|G|, g_eps), 0))."""
    bc_form: str = "loglik"
    """loglik (squashed-Gaussian log-likelihood of the buffer action, mean over action dims) |
    mse_sample (MSE of the reparameterised policy sample to it) | mse_mean (MSE of tanh(mu))."""
    g_source: str = "rmax"
    """rmax: G = largest episode return in the buffer | target: the task's success bar."""
    return_kind: str = "undiscounted"
    """undiscounted | discounted episode return R (computed by the buffer)."""
    g_eps: float = 1e-3
    """Floor of the denominator |G| of the exponent."""
    clip_exponent: bool = True
    """Clip (R - G) / |G| to <= 0 so omega <= beta even when R > G."""

    def __post_init__(self) -> None:
        _check(self.beta >= 0, "sirl.beta", self.beta, ">= 0")
        _check(self.g_eps > 0, "sirl.g_eps", self.g_eps, "> 0")
        _choice("sirl.bc_form", self.bc_form, BC_FORMS)
        _choice("sirl.g_source", self.g_source, G_SOURCES)
        _choice("sirl.return_kind", self.return_kind, RETURN_KINDS)


@dataclasses.dataclass(frozen=True)
class AgentConfig:
    """TD-MPC2 agent. Every default is the reference value (spec tdmpc2.md)."""

    # architecture (§1)
    model_size: str = "5M"
    """1M | 5M | 19M | 48M | 317M (reference presets) | tiny (tests only, not a reference size)."""
    enc_dim: int | None = None
    mlp_dim: int | None = None
    latent_dim: int | None = None
    num_enc_layers: int | None = None
    num_q: int | None = None
    simnorm_dim: int = 8
    num_bins: int = 101
    vmin: float = -10.0
    vmax: float = 10.0
    dropout: float = 0.01
    log_std_min: float = -10.0
    log_std_max: float = 2.0
    # planning (§3)
    mpc: bool = True
    horizon: int = 3
    iterations: int = 6
    """Base MPPI iterations; the agent adds 2 when the action size is >= 20 (`Agent.iterations`)."""
    num_samples: int = 512
    num_elites: int = 64
    num_pi_trajs: int = 24
    temperature: float = 0.5
    plan_env_chunk: int | None = None
    """0: plan all E envs in one vmap; k > 0: lax.map over chunks of k envs; None: 1 on CPU, 0 on
    accelerators. Not a reference field: results are identical, only speed and memory differ."""
    min_std: float = 0.05
    max_std: float = 2.0
    # losses and optimisation (§2)
    rho: float = 0.5
    consistency_coef: float = 20.0
    reward_coef: float = 0.1
    value_coef: float = 0.1
    entropy_coef: float = 1e-4
    entropy_form: str = "scaled"
    """scaled: current main, -A * pre-squash log density | v1: 2023/HB log-prob (spec §2.5)."""
    tau: float = 0.01
    lr: float = 3e-4
    enc_lr_scale: float = 0.3
    grad_clip_norm: float = 20.0
    pi_adam_eps: float = 1e-5
    batch_size: int = 256
    discount: float | None = None
    """None: from the episode length (§2.2)."""
    discount_denom: float = 5.0
    discount_min: float = 0.95
    discount_max: float = 0.995
    episodic: bool = False
    """True: (1 - terminated) in the TD target, a termination head trained with BCE, and MPPI
    masking of rewards / terminal Q after a predicted termination (spec §1.2, §2.3, §3)."""
    termination_coef: float = 1.0
    """Weight of the termination BCE in the world-model loss (used only when episodic)."""
    sirl: SirlConfig = dataclasses.field(default_factory=SirlConfig)

    def __post_init__(self) -> None:
        _choice("model_size", self.model_size, tuple(MODEL_PRESETS))
        _choice("entropy_form", self.entropy_form, ENTROPY_FORMS)
        for name in ("enc_dim", "mlp_dim", "latent_dim", "num_enc_layers", "num_q"):
            v = getattr(self, name)
            _check(v is None or v >= 1, name, v, "None (preset) or an int >= 1")
        _check(self.horizon >= 1, "horizon", self.horizon, "an int >= 1")
        _check(self.iterations >= 1, "iterations", self.iterations, "an int >= 1")
        _check(self.num_samples >= 1, "num_samples", self.num_samples, "an int >= 1")
        _check(
            1 <= self.num_elites <= self.num_samples,
            "num_elites",
            self.num_elites,
            f"1..num_samples ({self.num_samples})",
        )
        _check(
            0 <= self.num_pi_trajs < self.num_samples,
            "num_pi_trajs",
            self.num_pi_trajs,
            f"0..num_samples-1 ({self.num_samples - 1})",
        )
        _check(
            0 < self.min_std <= self.max_std,
            "min_std",
            self.min_std,
            f"0 < min_std <= max_std ({self.max_std})",
        )
        _check(
            self.plan_env_chunk is None or self.plan_env_chunk >= 0,
            "plan_env_chunk",
            self.plan_env_chunk,
            "None (auto) or an int >= 0",
        )
        _check(self.temperature > 0, "temperature", self.temperature, "> 0")
        _check(0 < self.rho <= 1, "rho", self.rho, "in (0, 1]")
        _check(self.lr > 0, "lr", self.lr, "> 0")
        _check(self.enc_lr_scale > 0, "enc_lr_scale", self.enc_lr_scale, "> 0")
        _check(self.grad_clip_norm > 0, "grad_clip_norm", self.grad_clip_norm, "> 0")
        _check(0 < self.tau <= 1, "tau", self.tau, "in (0, 1]")
        _check(self.batch_size >= 1, "batch_size", self.batch_size, "an int >= 1")
        _check(self.num_bins >= 2, "num_bins", self.num_bins, "an int >= 2")
        _check(self.vmin < self.vmax, "vmin", self.vmin, f"< vmax ({self.vmax})")
        _check(0 <= self.dropout < 1, "dropout", self.dropout, "in [0, 1)")
        _check(
            self.log_std_min < self.log_std_max, "log_std_min", self.log_std_min, "< log_std_max"
        )
        _check(
            self.discount is None or 0 < self.discount <= 1,
            "discount",
            self.discount,
            "None or in (0, 1]",
        )
        for name in (
            "consistency_coef",
            "reward_coef",
            "value_coef",
            "entropy_coef",
            "termination_coef",
        ):
            _check(getattr(self, name) >= 0, name, getattr(self, name), ">= 0")
        arch = self.arch
        _check(
            arch.latent_dim % self.simnorm_dim == 0,
            "latent_dim",
            arch.latent_dim,
            f"a multiple of simnorm_dim ({self.simnorm_dim})",
        )
        _check(arch.num_q >= 2, "num_q", arch.num_q, "an int >= 2 (two heads are drawn)")

    @property
    def arch(self) -> ModelArch:
        """Network widths: the `model_size` preset with explicit fields overriding it."""
        preset = MODEL_PRESETS[self.model_size]
        return ModelArch(
            *(
                getattr(self, f) if getattr(self, f) is not None else getattr(preset, f)
                for f in ModelArch._fields
            )
        )

    @classmethod
    def tiny(cls, **overrides) -> AgentConfig:
        """A small, fast, non-reference configuration for tests and CPU smoke runs."""
        base = dict(
            model_size="tiny",
            num_samples=32,
            num_elites=8,
            num_pi_trajs=4,
            iterations=2,
            batch_size=8,
        )
        base.update(overrides)
        return cls(**base)
