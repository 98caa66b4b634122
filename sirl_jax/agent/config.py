"""Agent configuration: TD-MPC2 defaults (spec §1-§3) plus the self-imitative term (spec §5).

Frozen dataclasses; nothing here is mutated at run time. Architecture fields default to None and
are resolved from `model_size` by `AgentConfig.arch`; explicit values override the preset.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

from sirl_jax.agent.checks import check, choice
from sirl_jax.agent.fasttd3_config import FastTD3Config


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
BC_REDUCTIONS = ("mean", "sum")
RMAX_MODES = ("in_buffer", "all_time")
KINDS = ("tdmpc2", "fasttd3")


@dataclasses.dataclass(frozen=True)
class SirlConfig:
    """The self-imitative BC term of TDMPBC (spec §5), and where its reference return G comes from.

    G is decided here and nowhere else: `g_source="rmax"` takes the replay buffer's R_max
    (computed by the buffer as `rmax_mode` says), `"target"` the task's success bar. The train
    step passes R_max to `Agent.update`; `Agent.sirl_reference` turns it into G.
    """

    enabled: bool = True
    """False: the plain TD-MPC2 policy update (no BC term computed at all)."""
    beta: float = 1.0
    """omega(R) = beta * exp(min((R - G) / max(|G|, g_eps), 0)); 0 reproduces TD-MPC2."""
    bc_form: str = "loglik"
    """loglik (squashed-Gaussian log-likelihood of the buffer action) | mse_sample (MSE of the
    reparameterised policy sample to it) | mse_mean (MSE of tanh(mu) to it)."""
    bc_reduce: str = "mean"
    """How the per-dimension BC terms combine: mean over the A action dimensions (keeps the term
    at the O(1) scale of Q/S) | sum (the paper's plain log pi; A times larger at the same fit)."""
    action_clip: float = 1e-6
    """loglik: buffer actions are clipped to +-(1 - action_clip) before atanh. MPPI clamps the
    actions it executes to +-1, so the clip decides how hard a clamped component pulls log sigma."""
    g_source: str = "rmax"
    """rmax: G = the replay buffer's R_max (see rmax_mode) | target: the task's success bar."""
    rmax_mode: str = "in_buffer"
    """R_max over the episodes live in the buffer (drops when the best is evicted; the paper's
    "currently in the replay buffer") | all_time: over every episode recorded so far."""
    return_kind: str = "undiscounted"
    """undiscounted | discounted episode return R (computed by the buffer)."""
    g_eps: float = 1e-3
    """Floor of the denominator |G| of the exponent."""
    clip_exponent: bool = True
    """Clip (R - G) / |G| to <= 0 so omega <= beta even when R > G."""

    def __post_init__(self) -> None:
        check(self.beta >= 0, "sirl.beta", self.beta, ">= 0")
        check(self.g_eps > 0, "sirl.g_eps", self.g_eps, "> 0")
        check(0 < self.action_clip < 1, "sirl.action_clip", self.action_clip, "in (0, 1)")
        choice("sirl.bc_form", self.bc_form, BC_FORMS)
        choice("sirl.bc_reduce", self.bc_reduce, BC_REDUCTIONS)
        choice("sirl.g_source", self.g_source, G_SOURCES)
        choice("sirl.rmax_mode", self.rmax_mode, RMAX_MODES)
        choice("sirl.return_kind", self.return_kind, RETURN_KINDS)


@dataclasses.dataclass(frozen=True)
class AgentConfig:
    """The agent: TD-MPC2 (every default is the reference value, spec tdmpc2.md) or FastTD3.

    `kind` is the one switch between the learners. Both read `sirl` (the self-imitative term)
    and share the replay buffer, train step, checkpoints, eval and export; FastTD3's own
    settings are `fasttd3`, and the TD-MPC2 fields below are unused under it.
    """

    kind: str = "tdmpc2"
    """tdmpc2 (world model + MPPI planner) | fasttd3 (deterministic actor, distributional
    clipped double-Q critic; settings in `fasttd3`)."""
    # architecture (§1)
    model_size: str = "5M"
    """1M | 5M | 19M | 48M | 317M (reference presets) | tiny (tests only, not a reference size)."""
    enc_dim: int | None = None
    """Encoder hidden width (None: from model_size)."""
    mlp_dim: int | None = None
    """Hidden width of dynamics, reward, policy and Q heads (None: from model_size)."""
    latent_dim: int | None = None
    """Latent size Z, a multiple of simnorm_dim (None: from model_size)."""
    num_enc_layers: int | None = None
    """Encoder layers (None: from model_size)."""
    num_q: int | None = None
    """Q ensemble members, >= 2 (None: from model_size; 5 for 5M)."""
    simnorm_dim: int = 8
    """SimNorm group size of the latent."""
    num_bins: int = 101
    """Two-hot bins of the reward and Q heads (over symlog space)."""
    vmin: float = -10.0
    """Lowest bin centre, in symlog space."""
    vmax: float = 10.0
    """Highest bin centre, in symlog space."""
    dropout: float = 0.01
    """Dropout after the first layer of each Q member (online Q in the losses only)."""
    log_std_min: float = -10.0
    """Lower bound of the policy's log sigma."""
    log_std_max: float = 2.0
    """Upper bound of the policy's log sigma."""
    # planning (§3)
    mpc: bool = True
    """Act with MPPI; False acts with the policy prior alone."""
    horizon: int = 3
    """H, the planning and training horizon."""
    iterations: int = 6
    """Base MPPI iterations; the agent adds 2 when the action size is >= 20 (`Agent.iterations`)."""
    num_samples: int = 512
    """MPPI sequences per iteration, the policy trajectories included."""
    num_elites: int = 64
    """Top sequences the MPPI mean and std are refitted to."""
    num_pi_trajs: int = 24
    """Of num_samples, sequences rolled out by the policy prior."""
    temperature: float = 0.5
    """Inverse temperature of the elite scores exp(temperature * (V - max V))."""
    plan_env_chunk: int | None = None
    """0: plan all E envs in one vmap; k > 0: lax.map over chunks of k envs; None: 1 on CPU, 0 on
    accelerators. Not a reference field: results are identical, only speed and memory differ."""
    min_std: float = 0.05
    """Lower clamp of the MPPI std."""
    max_std: float = 2.0
    """Upper clamp, and the std every plan starts from."""
    # losses and optimisation (§2)
    rho: float = 0.5
    """Temporal weight rho^t of the losses over the horizon."""
    consistency_coef: float = 20.0
    """Weight of the latent consistency loss."""
    reward_coef: float = 0.1
    """Weight of the reward cross-entropy."""
    value_coef: float = 0.1
    """Weight of the Q cross-entropy."""
    entropy_coef: float = 1e-4
    """alpha, the policy's entropy bonus."""
    entropy_form: str = "scaled"
    """scaled: current main, -A * pre-squash log density | v1: 2023/HB log-prob (spec §2.5)."""
    tau: float = 0.01
    """Polyak rate of the target Qs, and the rate of the running Q scale."""
    lr: float = 3e-4
    """Adam learning rate (world model and policy)."""
    enc_lr_scale: float = 0.3
    """The encoder's learning rate is lr * enc_lr_scale."""
    grad_clip_norm: float = 20.0
    """Global gradient-norm clip of each optimiser."""
    pi_adam_eps: float = 1e-5
    """Adam epsilon of the policy optimiser."""
    batch_size: int = 256
    """B, sub-trajectories per update."""
    discount: float | None = None
    """gamma; None: from the episode length (§2.2)."""
    discount_denom: float = 5.0
    """With discount None: gamma = clip((T/denom - 1) / (T/denom), discount_min, discount_max)."""
    discount_min: float = 0.95
    """Lower clip of the heuristic gamma."""
    discount_max: float = 0.995
    """Upper clip of the heuristic gamma."""
    episodic: bool = False
    """True: (1 - terminated) in the TD target, a termination head trained with BCE, and MPPI
    masking of rewards / terminal Q after a predicted termination (spec §1.2, §2.3, §3)."""
    termination_coef: float = 1.0
    """Weight of the termination BCE in the world-model loss (used only when episodic)."""
    sirl: SirlConfig = dataclasses.field(default_factory=SirlConfig)
    fasttd3: FastTD3Config = dataclasses.field(default_factory=FastTD3Config)
    """FastTD3's settings (used when kind is fasttd3)."""

    def __post_init__(self) -> None:
        choice("kind", self.kind, KINDS)
        if self.kind == "fasttd3" and self.sirl.enabled:
            check(self.sirl.bc_form == "mse_mean", "sirl.bc_form", self.sirl.bc_form,
                  "'mse_mean' with kind='fasttd3' (its actor is deterministic: no likelihood, "
                  "no sample)")  # fmt: skip
        choice("model_size", self.model_size, tuple(MODEL_PRESETS))
        choice("entropy_form", self.entropy_form, ENTROPY_FORMS)
        for name in ("enc_dim", "mlp_dim", "latent_dim", "num_enc_layers", "num_q"):
            v = getattr(self, name)
            check(v is None or v >= 1, name, v, "None (preset) or an int >= 1")
        check(self.horizon >= 1, "horizon", self.horizon, "an int >= 1")
        check(self.iterations >= 1, "iterations", self.iterations, "an int >= 1")
        check(self.num_samples >= 1, "num_samples", self.num_samples, "an int >= 1")
        check(
            1 <= self.num_elites <= self.num_samples,
            "num_elites",
            self.num_elites,
            f"1..num_samples ({self.num_samples})",
        )
        check(
            0 <= self.num_pi_trajs < self.num_samples,
            "num_pi_trajs",
            self.num_pi_trajs,
            f"0..num_samples-1 ({self.num_samples - 1})",
        )
        check(
            0 < self.min_std <= self.max_std,
            "min_std",
            self.min_std,
            f"0 < min_std <= max_std ({self.max_std})",
        )
        check(
            self.plan_env_chunk is None or self.plan_env_chunk >= 0,
            "plan_env_chunk",
            self.plan_env_chunk,
            "None (auto) or an int >= 0",
        )
        check(self.temperature > 0, "temperature", self.temperature, "> 0")
        check(0 < self.rho <= 1, "rho", self.rho, "in (0, 1]")
        check(self.lr > 0, "lr", self.lr, "> 0")
        check(self.enc_lr_scale > 0, "enc_lr_scale", self.enc_lr_scale, "> 0")
        check(self.grad_clip_norm > 0, "grad_clip_norm", self.grad_clip_norm, "> 0")
        check(0 < self.tau <= 1, "tau", self.tau, "in (0, 1]")
        check(self.batch_size >= 1, "batch_size", self.batch_size, "an int >= 1")
        check(self.num_bins >= 2, "num_bins", self.num_bins, "an int >= 2")
        check(self.vmin < self.vmax, "vmin", self.vmin, f"< vmax ({self.vmax})")
        check(0 <= self.dropout < 1, "dropout", self.dropout, "in [0, 1)")
        check(
            self.log_std_min < self.log_std_max, "log_std_min", self.log_std_min, "< log_std_max"
        )
        check(
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
            check(getattr(self, name) >= 0, name, getattr(self, name), ">= 0")
        arch = self.arch
        check(
            arch.latent_dim % self.simnorm_dim == 0,
            "latent_dim",
            arch.latent_dim,
            f"a multiple of simnorm_dim ({self.simnorm_dim})",
        )
        check(arch.num_q >= 2, "num_q", arch.num_q, "an int >= 2 (two heads are drawn)")

    @property
    def plans(self) -> bool:
        """The agent acts (and is evaluated) with an MPPI planner besides its policy."""
        return self.kind == "tdmpc2" and self.mpc

    @property
    def window(self) -> int:
        """Transitions per replay sample: TD-MPC2's horizon H, FastTD3's n-step n."""
        return self.horizon if self.kind == "tdmpc2" else self.fasttd3.n_steps

    @property
    def sample_size(self) -> int:
        """Windows per replay sample: TD-MPC2's batch; FastTD3's batch for each of the
        `policy_frequency` critic updates one `Agent.update` runs."""
        if self.kind == "tdmpc2":
            return self.batch_size
        return self.fasttd3.batch_size * self.fasttd3.policy_frequency

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

    # The two non-reference agents, each defined here once; `overrides` replace any field.

    @classmethod
    def tiny(cls, **overrides) -> AgentConfig:
        """The fastest agent, for tests and CPU smoke runs (the `smoke` preset's, with batch 32):
        the tiny model (32 wide, 5 Qs), MPPI 32 x 2 with 8 elites and 4 policy trajectories,
        batch 8."""
        base = dict(
            model_size="tiny",
            num_samples=32,
            num_elites=8,
            num_pi_trajs=4,
            iterations=2,
            batch_size=8,
        )
        return cls(**{**base, **overrides})

    @classmethod
    def small(cls, **overrides) -> AgentConfig:
        """The CPU learning agent (the `cpu` preset's, and the CPU stand-in of the paper's runs):
        `tiny` widened to latent 64, MLP 128, encoder 64, 2 Qs, MPPI 64 x 2 with 8 elites and 8
        policy trajectories, batch 64."""
        widened = dict(latent_dim=64, mlp_dim=128, enc_dim=64, num_q=2, num_samples=64,
                       num_pi_trajs=8, batch_size=64)  # fmt: skip
        return cls.tiny(**{**widened, **overrides})
