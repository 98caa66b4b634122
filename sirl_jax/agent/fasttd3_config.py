"""FastTD3's settings (`agent.kind="fasttd3"`): every default is the reference value.

The reference is FastTD3's repository (younggyoseo/FastTD3, `fast_td3/hyperparams.py`,
`BaseArgs` for HumanoidBench). The fields it sets there per task (`v_min`/`v_max` for reach,
maze and push) are listed in docs/agent.md; everything else is shared by its HumanoidBench tasks.
"""

from __future__ import annotations

import dataclasses

from sirl_jax.agent.checks import check


@dataclasses.dataclass(frozen=True)
class FastTD3Config:
    """FastTD3: a deterministic actor, a distributional (C51) clipped double-Q critic, n-step
    targets, per-env exploration noise, AdamW, large batches from many parallel envs."""

    actor_hidden_dim: int = 512
    """Actor MLP widths: h, h/2, h/4 (ReLU), then A outputs through tanh."""
    critic_hidden_dim: int = 1024
    """Critic MLP widths: h, h/2, h/4 (ReLU), then num_atoms logits; two critics."""
    init_scale: float = 0.01
    """Std of the normal init of the actor's output layer (its bias is zero)."""
    num_atoms: int = 101
    """Atoms of the critic's categorical return distribution."""
    v_min: float = -250.0
    """Lowest atom (the support is linspace(v_min, v_max, num_atoms))."""
    v_max: float = 250.0
    """Highest atom."""
    gamma: float = 0.99
    """Discount per env step."""
    n_steps: int = 1
    """n of the n-step return (the replay window). 1 is FastTD3's HumanoidBench setting."""
    tau: float = 0.1
    """Polyak rate of the target critic, applied after every critic update."""
    batch_size: int = 32768
    """Transitions per critic update."""
    num_updates: int = 2
    """Critic updates per vectorised env step (all envs together); replaces `train.utd`."""
    policy_frequency: int = 2
    """One actor update per this many critic updates (TD3's delay)."""
    actor_lr: float = 3e-4
    """AdamW learning rate of the actor (FastTD3's cosine schedule ends at the same value)."""
    critic_lr: float = 3e-4
    """AdamW learning rate of the critics."""
    weight_decay: float = 0.1
    """AdamW's decoupled weight decay (both optimisers)."""
    policy_noise: float = 0.001
    """Std of the target policy smoothing noise."""
    noise_clip: float = 0.5
    """Clip of the target policy smoothing noise."""
    std_min: float = 0.001
    """Lowest per-env exploration noise std (each env draws its std in [std_min, std_max]
    uniformly at the start of every episode)."""
    std_max: float = 0.4
    """Highest per-env exploration noise std."""
    use_cdq: bool = True
    """Clipped double Q: the target distribution of the critic with the lower mean, and the
    actor maximises min(Q1, Q2); False: each critic its own target, the actor the mean."""
    obs_normalization: bool = True
    """Normalise observations by running mean and std (updated from every sampled batch)."""
    obs_norm_eps: float = 1e-2
    """(obs - mean) / (std + eps)."""
    sirl_scale_tau: float = 0.01
    """Rate of the running Q scale S that puts the self-imitative term on TDMPBC's footing:
    the actor loss is -Q + sg(S) * omega * BC, i.e. S times TDMPBC's -Q/S + omega * BC."""
    replay_sampling: str = "transition"
    """How the replay draws its windows (`buffer.SAMPLINGS`): "transition", uniformly among all
    transitions of the finished episodes, as FastTD3's replay draws; "episode", an episode
    uniformly and then a window in it (TD-MPC2's SliceSampler: a transition of a 30-step fall
    is drawn 33x as often as one of a 1,000-step episode). The FastTD3 studies before this
    field existed ran "episode" (their commands pin it)."""
    actor_ema: float = 0.0
    """A departure from FastTD3, off at 0: the Polyak rate of an averaged copy of the actor,
    stepped after every actor update. That copy acts (with the exploration noise), is
    evaluated and is exported; the trained actor still gives the critics' target actions.
    In FastTD3 the trained actor acts itself (0). docs/agent.md gives the pilot's numbers."""

    def __post_init__(self) -> None:
        for name in ("actor_hidden_dim", "critic_hidden_dim"):
            v = getattr(self, name)
            check(v >= 4, f"fasttd3.{name}", v, "an int >= 4 (h/4 must be >= 1)")
        for name in ("n_steps", "batch_size", "num_updates", "policy_frequency"):
            v = getattr(self, name)
            check(v >= 1, f"fasttd3.{name}", v, "an int >= 1")
        check(self.num_atoms >= 2, "fasttd3.num_atoms", self.num_atoms, "an int >= 2")
        check(self.v_min < self.v_max, "fasttd3.v_min", self.v_min, f"< v_max ({self.v_max})")
        check(0 < self.gamma <= 1, "fasttd3.gamma", self.gamma, "in (0, 1]")
        check(0 < self.tau <= 1, "fasttd3.tau", self.tau, "in (0, 1]")
        check(self.replay_sampling in ("episode", "transition"), "fasttd3.replay_sampling",
              self.replay_sampling, "one of episode, transition")  # fmt: skip
        check(0 <= self.actor_ema <= 1, "fasttd3.actor_ema", self.actor_ema,
              "in [0, 1] (0: no averaged actor)")  # fmt: skip
        check(0 < self.sirl_scale_tau <= 1, "fasttd3.sirl_scale_tau", self.sirl_scale_tau,
              "in (0, 1]")  # fmt: skip
        for name in ("actor_lr", "critic_lr", "init_scale", "obs_norm_eps"):
            v = getattr(self, name)
            check(v > 0, f"fasttd3.{name}", v, "> 0")
        for name in ("weight_decay", "policy_noise", "noise_clip"):
            v = getattr(self, name)
            check(v >= 0, f"fasttd3.{name}", v, ">= 0")
        check(0 <= self.std_min <= self.std_max, "fasttd3.std_min", self.std_min,
              f"0 <= std_min <= std_max ({self.std_max})")  # fmt: skip

    @property
    def updates_per_step(self) -> float:
        """`Agent.update` calls per vectorised env step: each runs `policy_frequency` critic
        updates and one actor update, so `num_updates` critic updates happen per step."""
        return self.num_updates / self.policy_frequency
