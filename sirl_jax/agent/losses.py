"""TD-MPC2 losses (spec §2.3, §2.5) and the TDMPBC self-imitative term (spec §5).

Shapes: H horizon, B batch, A action, Z latent, O observation, Q num_q.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sirl_jax.agent import math as am
from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.agent.hyper import Hyper
from sirl_jax.agent.world_model import (
    LOG_2PI,
    PolicyOutput,
    WorldModel,
    squashed_log_likelihood_dims,
)
from sirl_jax.types import Batch

sg = jax.lax.stop_gradient


def rho_weights(rho: float, n: int) -> jax.Array:
    """[n] temporal weights rho^t, t = 0..n-1."""
    return jnp.asarray(rho, jnp.float32) ** jnp.arange(n, dtype=jnp.float32)


def td_target(
    reward: jax.Array, q_next: jax.Array, terminated: jax.Array, discount: float, episodic: bool
) -> jax.Array:
    """y = r + gamma * (1 - d) * q_next; the mask only when episodic (HB bootstraps falls)."""
    cont = 1.0 - terminated if episodic else 1.0
    return reward + discount * cont * q_next


def bce_with_logits(logits: jax.Array, targets: jax.Array) -> jax.Array:
    """Elementwise -[d log sigmoid(x) + (1 - d) log(1 - sigmoid(x))], overflow-free form."""
    return jnp.maximum(logits, 0.0) - logits * targets + jnp.log1p(jnp.exp(-jnp.abs(logits)))


def update_scale(scale: jax.Array, q0: jax.Array, tau: float) -> jax.Array:
    """RunningScale: S + tau * (max(1, P95 - P5) - S), percentiles over q0 [B] ('linear')."""
    p5, p95 = jnp.percentile(q0, jnp.array([5.0, 95.0]), method="linear")
    return scale + tau * (jnp.maximum(1.0, p95 - p5) - scale)


def sirl_weight(episode_return: jax.Array, return_ref: jax.Array, sirl: SirlConfig,
                beta: jax.Array | None = None) -> jax.Array:  # fmt: skip
    """omega(R) = beta * exp((R - G) / max(|G|, g_eps)), exponent clipped to <= 0 ([B] -> [B]).

    beta: the run's traced weight (`state.hyper`, `sirl_jax.agent.hyper`); None: `sirl.beta`.

    The paper's exp((R - G) / G) flips sign for G < 0 and exceeds beta for R > G; the floored |G|
    denominator and the clip keep omega in (0, beta] and increasing in R for every G.
    """
    x = (episode_return - return_ref) / jnp.maximum(jnp.abs(return_ref), sirl.g_eps)
    if sirl.clip_exponent:
        x = jnp.minimum(x, 0.0)
    return sg((sirl.beta if beta is None else beta) * jnp.exp(x))


def world_model_loss(
    wm: WorldModel,
    cfg: AgentConfig,
    discount: float,
    wm_params: dict,
    policy_params: dict,
    target_qs: dict,
    batch: Batch,
    key: jax.Array,
    h: Hyper | None = None,
) -> tuple[jax.Array, tuple[jax.Array, dict]]:
    """L = c_c * L_c + c_r * L_r + c_q * L_q (+ c_d * L_d when episodic) (spec §2.3).

    h: the run's per-run scalars (`state.hyper`; the coefficients); None: `cfg`'s.

    L_d = mean over H and B of BCE(termination(z_{t+1}), d_t), t = 0..H-1, on the rollout
    latents z_1..z_H with gradients (unweighted by rho, as in the reference). The metric
    'termination_loss' is 0 when not episodic, so the metric set is the same either way.

    Returns:
      loss []; aux = (rollout latents z_0..z_H [H+1, B, Z] with gradients, metrics).
    """
    k_pi, k_pair, k_drop = jax.random.split(key, 3)
    params = {**wm_params, "policy": policy_params}
    H = batch.action.shape[0]
    w = rho_weights(cfg.rho, H)

    z_next = sg(wm.encode(params, batch.obs[1:]))  # [H, B, Z] online encoder, no target encoder

    def step(z_t, a_t):
        z_tp1 = wm.next(params, z_t, a_t)
        return z_tp1, z_tp1

    z_0 = wm.encode(params, batch.obs[0])
    _, z_roll = jax.lax.scan(step, z_0, batch.action)
    zs = jnp.concatenate([z_0[None], z_roll], axis=0)  # [H+1, B, Z]

    pi_next = wm.pi(params, z_next, k_pi)  # a stochastic sample, not the mean
    q_next = wm.q_pair(target_qs, z_next, pi_next.action, k_pair, "min", None)
    y = sg(td_target(batch.reward, q_next, batch.terminated, discount, cfg.episodic))  # [H, B]

    consistency = jnp.mean((z_roll - z_next) ** 2, axis=(1, 2))  # [H]
    r_logits = wm.reward_logits(params, zs[:-1], batch.action)
    reward_ce = am.two_hot_ce(r_logits, batch.reward, cfg.num_bins, cfg.vmin, cfg.vmax)
    q_logits = wm.q_logits(wm_params["qs"], zs[:-1], batch.action, k_drop)  # [Q, H, B, bins]
    value_ce = am.two_hot_ce(q_logits, y[None], cfg.num_bins, cfg.vmin, cfg.vmax)

    l_c = jnp.sum(w * consistency) / H
    l_r = jnp.sum(w * reward_ce.mean(axis=1)) / H
    l_q = jnp.sum(w * value_ce.mean(axis=2).sum(axis=0)) / (H * value_ce.shape[0])
    h = Hyper.of(cfg, h)
    loss = h["consistency_coef"] * l_c + h["reward_coef"] * l_r + h["value_coef"] * l_q
    if cfg.episodic:
        d_logits = wm.termination_logit(params, z_roll)  # [H, B] on z_1..z_H
        l_d = jnp.mean(bce_with_logits(d_logits, batch.terminated.astype(d_logits.dtype)))
        loss = loss + cfg.termination_coef * l_d
    else:
        l_d = jnp.zeros(())
    metrics = {
        "consistency_loss": l_c,
        "reward_loss": l_r,
        "value_loss": l_q,
        "termination_loss": l_d,
        "wm_loss": loss,
        "td_target_mean": jnp.mean(y),
    }
    return loss, (zs, metrics)


def bc_term(cfg: AgentConfig, pi_out: PolicyOutput, actions: jax.Array, omega: jax.Array):
    """Self-imitative BC per step: [H, B] loss terms (to be rho-weighted).

    pi_out is the policy-loss forward pass on z_0..z_H ([H+1, B, ...]); the term reuses its
    first H steps instead of running the policy network again. Per action dimension the term
    is -log pi_i(a_i | z_t) (loglik) or the squared error (mse_*); `sirl.bc_reduce` combines
    the A dimensions by their mean (the default: O(1) like Q/S, where the paper's plain sum of
    a 61-dim log density reaches hundreds) or their sum (the paper's log pi).
    """
    sirl = cfg.sirl
    if sirl.bc_form == "loglik":
        per_dim = -squashed_log_likelihood_dims(
            pi_out.mu[:-1], pi_out.log_std[:-1], actions, sirl.action_clip
        )
    elif sirl.bc_form == "mse_sample":
        per_dim = (pi_out.action[:-1] - actions) ** 2
    else:
        per_dim = (pi_out.mean_action[:-1] - actions) ** 2
    reduce = jnp.mean if sirl.bc_reduce == "mean" else jnp.sum
    return omega[None] * reduce(per_dim, axis=-1)


def clamped_fraction(actions: jax.Array, clip: float) -> jax.Array:
    """[] fraction of action components at the clamp, |a| >= 1 - clip (MPPI clamps to +-1)."""
    return jnp.mean((jnp.abs(actions) >= 1.0 - clip).astype(jnp.float32))


def policy_loss(
    wm: WorldModel,
    cfg: AgentConfig,
    policy_params: dict,
    qs_params: dict,
    zs: jax.Array,
    scale: jax.Array,
    batch: Batch,
    return_ref: jax.Array,
    key: jax.Array,
    h: Hyper | None = None,
) -> tuple[jax.Array, tuple[jax.Array, dict]]:
    """Policy-prior loss (spec §2.5) plus, when cfg.sirl.enabled, the BC term (spec §5).

    Args:
      zs: [H+1, B, Z] detached rollout latents; qs_params: detached, updated online Q params.
      return_ref: [] G of the self-imitative weight (`Agent.sirl_reference`).
      h: the run's per-run scalars (`state.hyper`: beta, tau, entropy_coef); None: `cfg`'s.
    Returns:
      loss []; aux = (updated running scale [], metrics).
    """
    k_sample, k_pair, k_drop = jax.random.split(key, 3)
    h = Hyper.of(cfg, h)
    Hp1 = zs.shape[0]
    A = batch.action.shape[-1]
    w = rho_weights(cfg.rho, Hp1)
    out = wm.pi({"policy": policy_params}, zs, k_sample)  # [H+1, B, A]
    q = wm.q_pair(qs_params, zs, out.action, k_pair, "avg", k_drop)  # [H+1, B], dropout on
    new_scale = update_scale(scale, sg(q[0]), h["tau"])  # updated before use
    if cfg.entropy_form == "scaled":
        # -alpha * E with E = -A * l_g (current main; the ratio form's gradient away from l_s=-1e-8)
        ent_term = h["entropy_coef"] * A * out.log_prob_gauss
    else:
        # 2023 / HumanoidBench fork: A-scaled Gaussian part, unscaled tanh correction.
        gauss = jnp.sum(-0.5 * out.eps**2 - out.log_std, axis=-1) - 0.5 * LOG_2PI
        tanh_corr = jnp.sum(jnp.log(jnp.maximum(0.0, 1.0 - out.action**2) + 1e-6), axis=-1)
        ent_term = h["entropy_coef"] * (A * gauss - tanh_corr)
    rl = jnp.sum(w * jnp.mean(ent_term - q / new_scale, axis=1)) / Hp1
    metrics = {
        "pi_rl_loss": rl,
        "pi_scale": new_scale,
        "pi_entropy": jnp.mean(-out.log_prob),
        "pi_log_std": jnp.mean(out.log_std),
        "pi_q": jnp.mean(q),
    }
    loss = rl
    if cfg.sirl.enabled:
        omega = sirl_weight(batch.episode_return, return_ref, cfg.sirl, h["sirl.beta"])
        bc = bc_term(cfg, out, batch.action, omega)
        bc_loss = jnp.sum(w[:-1] * jnp.mean(bc, axis=1)) / Hp1
        loss = rl + bc_loss
        metrics["sirl_loss"] = bc_loss
        metrics["sirl_weight_mean"] = jnp.mean(omega)
    else:
        metrics["sirl_loss"] = jnp.zeros(())
        metrics["sirl_weight_mean"] = jnp.zeros(())
    metrics["sirl/clamped_fraction"] = clamped_fraction(batch.action, cfg.sirl.action_clip)
    metrics["pi_loss"] = loss
    return loss, (new_scale, metrics)
