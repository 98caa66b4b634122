"""`make_fasttd3`: FastTD3 (Seo et al. 2025) with the TDMPBC self-imitative term, as an `Agent`.

The reference is FastTD3's repository (younggyoseo/FastTD3: `fast_td3/fast_td3.py`,
`fast_td3/train.py`, `fast_td3/hyperparams.py`). Per `Agent.update` call (one "update group"):

  for i in 0..P-1 (P = policy_frequency), each on its own batch of B transitions:
    observation stats <- batch's s_0, then its s_n (running mean / var, as FastTD3 normalises
      both with its training-mode normaliser);
    critic: both distributional critics regress, by cross-entropy, onto the categorical
      projection of r^(n) + gamma^n (1 - d) z under the target critics at
      (s_n, clip(actor(s_n) + clip(eps * policy_noise, +-noise_clip), +-1)), the online actor
      (FastTD3 has no target actor); with clipped double Q both take the projected
      distribution of the target critic with the lower mean;
    after the last critic step: the actor maximises min(Q1, Q2) (mean without CDQ);
    target critics <- Polyak(tau).

The self-imitative term joins the actor loss as TDMPBC defines it relative to the RL term:
TDMPBC minimises -Q/S + omega(R) * BC with S TD-MPC2's running Q scale; FastTD3's actor loss is
-Q, so the term enters as sg(S) * omega(R) * BC (the same loss times S). BC is the mean over
action dimensions of (actor(s_0) - a_0)^2, a_0 the buffer action (the actor is deterministic).
With `sirl.enabled=False` or beta = 0 the loss is FastTD3's own, exactly.

Shape letters: B batch, P policy_frequency, N atoms, O observation, A action, E envs.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax
from flax import struct

from sirl_jax.agent import losses
from sirl_jax.agent.agent import Agent, check_sizes, make_sirl_reference, polyak
from sirl_jax.agent.config import AgentConfig
from sirl_jax.agent.fasttd3_nets import ObsNorm, ReluMLP, project, widths
from sirl_jax.agent.hyper import Hyper
from sirl_jax.types import Batch

sg = jax.lax.stop_gradient




def export_params(state) -> dict:
    """What `export` writes to params.npz: the networks (the averaged actor as 'actor' when
    `fasttd3.actor_ema` keeps one) and the observation statistics."""
    params = dict(state.params)
    if "actor_ema" in params:
        params["actor"] = params.pop("actor_ema")
    return {**params, "obs_norm": {"mean": state.obs_norm.mean, "var": state.obs_norm.var}}


def policy_from_params(cfg: AgentConfig, action_size: int, params: dict):
    """obs [..., O] -> the actor's eval-mode action [..., A], from `export_params`' dict."""
    fc = cfg.fasttd3
    actor = ReluMLP(widths(fc.actor_hidden_dim), action_size, fc.init_scale, tanh=True)
    norm = ObsNorm(params["obs_norm"]["mean"], params["obs_norm"]["var"], jnp.zeros(()))

    def policy(obs):
        if fc.obs_normalization:
            obs = norm(obs, fc.obs_norm_eps)
        return actor.apply({"params": params["actor"]}, obs)

    return policy


@struct.dataclass
class FastTD3State:
    """params: {'actor', 'critic'} with the two critics stacked on a leading [2] axis, and
    'actor_ema' (the averaged actor that acts) when `fasttd3.actor_ema` > 0;
    target_critic: Polyak copy of 'critic'; obs_norm: observation statistics; scale: [] the
    running Q scale S of the self-imitative term; hyper: the run's per-run scalars
    (`sirl_jax.agent.hyper`)."""

    params: dict
    target_critic: dict
    actor_opt_state: optax.OptState
    critic_opt_state: optax.OptState
    obs_norm: ObsNorm
    scale: jax.Array
    hyper: dict


@struct.dataclass
class NoiseState:
    """Per-env exploration noise std [E, 1], redrawn at each env's first step."""

    std: jax.Array


def make_fasttd3(
    cfg: AgentConfig, obs_size: int, action_size: int, episode_length: int,
    success_bar: float | None = None,
) -> Agent:  # fmt: skip
    """Builds FastTD3 (+ the self-imitative term when `cfg.sirl.enabled`) for static sizes."""
    check_sizes(cfg, obs_size, action_size, episode_length, success_bar)
    sirl_reference = make_sirl_reference(cfg, success_bar)
    fc = cfg.fasttd3
    A, P, n = action_size, fc.policy_frequency, fc.n_steps
    actor = ReluMLP(widths(fc.actor_hidden_dim), A, fc.init_scale, tanh=True)
    critic = ReluMLP(widths(fc.critic_hidden_dim), fc.num_atoms)
    support = jnp.linspace(fc.v_min, fc.v_max, fc.num_atoms)

    def adamw(h: Hyper, which: str) -> optax.GradientTransformation:
        """AdamW at the run's traced rate and decay (`state.hyper`); its state is the same
        whatever the values, so `init` builds it from the config's."""
        return optax.adamw(h[f"fasttd3.{which}_lr"], weight_decay=h["fasttd3.weight_decay"])

    gammas = fc.gamma ** jnp.arange(n, dtype=jnp.float32)

    def normalize(norm: ObsNorm, x):
        return norm(x, fc.obs_norm_eps) if fc.obs_normalization else x

    def observe(norm: ObsNorm, x):
        """FastTD3's training-mode normaliser: update the statistics with x, then apply them."""
        norm = norm.update(x) if fc.obs_normalization else norm
        return norm, normalize(norm, x)

    def critic_logits(critic_params, obs, action):
        """[2, B, N] logits of both critics."""
        x = jnp.concatenate([obs, action], axis=-1)
        return jax.vmap(lambda p: critic.apply({"params": p}, x))(critic_params)

    def values(logits):
        return jnp.sum(jax.nn.softmax(logits, axis=-1) * support, axis=-1)

    def init(key: jax.Array) -> FastTD3State:
        h0 = Hyper.of(cfg)
        k_actor, k_critic = jax.random.split(key)
        obs, act = jnp.zeros((1, obs_size)), jnp.zeros((1, obs_size + A))
        params = {
            "actor": actor.init(k_actor, obs)["params"],
            "critic": jax.vmap(lambda k: critic.init(k, act)["params"])(
                jax.random.split(k_critic, 2)),
        }  # fmt: skip
        if fc.actor_ema > 0:
            params["actor_ema"] = jax.tree_util.tree_map(jnp.copy, params["actor"])
        return FastTD3State(
            params=params,
            target_critic=jax.tree_util.tree_map(jnp.copy, params["critic"]),
            actor_opt_state=adamw(h0, "actor").init(params["actor"]),
            critic_opt_state=adamw(h0, "critic").init(params["critic"]),
            obs_norm=ObsNorm.init(obs_size),
            scale=jnp.ones((), jnp.float32),
            hyper=h0.hyper,
        )

    def critic_loss(critic_params, target_critic, actor_params, s0, a0, sn, ret, boot, key, h):
        clip = h["fasttd3.noise_clip"]
        noise = jnp.clip(jax.random.normal(key, a0.shape) * h["fasttd3.policy_noise"], -clip, clip)
        next_action = jnp.clip(actor.apply({"params": actor_params}, sn) + noise, -1.0, 1.0)
        target_probs = jax.nn.softmax(critic_logits(target_critic, sn, next_action), axis=-1)
        proj = jax.vmap(lambda p: project(p, ret, boot, fc.gamma**n, support, fc.v_min,
                                          fc.v_max))(target_probs)  # fmt: skip
        proj_values = jnp.sum(proj * support, axis=-1)  # [2, B]
        if fc.use_cdq:
            lower = jnp.where((proj_values[0] < proj_values[1])[:, None], proj[0], proj[1])
            proj = jnp.stack([lower, lower])
        proj = sg(proj)
        logp = jax.nn.log_softmax(critic_logits(critic_params, s0, a0), axis=-1)
        ce = -jnp.sum(proj * logp, axis=-1)  # [2, B]
        loss = jnp.sum(jnp.mean(ce, axis=1))  # qf1_loss + qf2_loss
        return loss, {"qf_loss": loss, "qf_target_mean": jnp.mean(proj_values[0])}

    def actor_loss(actor_params, critic_params, scale, s0, a0, episode_return, return_ref, beta):
        action = actor.apply({"params": actor_params}, s0)
        q = values(critic_logits(critic_params, s0, action))  # [2, B]
        q = jnp.min(q, axis=0) if fc.use_cdq else jnp.mean(q, axis=0)
        rl = -jnp.mean(q)
        new_scale = losses.update_scale(scale, sg(q), fc.sirl_scale_tau)
        metrics = {"actor_loss": rl, "pi_q": jnp.mean(q), "pi_scale": new_scale,
                   "sirl/clamped_fraction": losses.clamped_fraction(a0, cfg.sirl.action_clip)}
        if not cfg.sirl.enabled:
            zero = jnp.zeros(())
            return rl, (new_scale, {**metrics, "sirl_loss": zero, "sirl_weight_mean": zero,
                                    "pi_loss": rl})  # fmt: skip
        omega = losses.sirl_weight(episode_return, return_ref, cfg.sirl, beta)
        bc = jnp.mean(jnp.square(action - a0), axis=-1)  # [B]
        sirl_loss = sg(new_scale) * jnp.mean(omega * bc)
        loss = rl + sirl_loss
        return loss, (new_scale, {**metrics, "sirl_loss": sirl_loss,
                                  "sirl_weight_mean": jnp.mean(omega), "pi_loss": loss})

    def groups(batch: Batch) -> Batch:
        """The P batches of B windows one update group uses: [.., P * B, ..] -> [P, .., B, ..]
        (the B axis is 0 for episode_return, 1 for the time-major fields)."""

        def split(x):
            axis = 0 if x.ndim == 1 else 1
            x = x.reshape(x.shape[:axis] + (P, -1) + x.shape[axis + 1:])
            return jnp.moveaxis(x, axis, 0)

        return jax.tree_util.tree_map(split, batch)

    def critic_step(actor_params, h, carry, xs):
        """One critic update on one batch, then the target's Polyak step."""
        critic, target, norm, opt = carry
        b, key = xs
        norm, s0 = observe(norm, b.obs[0])
        norm, sn = observe(norm, b.obs[n])
        alive = jnp.cumprod(1.0 - b.terminated, axis=0)  # [n, B] after step k
        ret = jnp.sum(gammas[:, None] * jnp.concatenate(
            [jnp.ones_like(alive[:1]), alive[:-1]]) * b.reward, axis=0)  # fmt: skip
        (_, m), grads = jax.value_and_grad(critic_loss, has_aux=True)(
            critic, target, actor_params, s0, b.action[0], sn, ret, alive[-1], key, h)
        upd, opt = adamw(h, "critic").update(grads, opt, critic)
        critic = optax.apply_updates(critic, upd)
        m["critic_grad_norm"] = optax.tree.norm(grads)
        return (critic, polyak(target, critic, h["fasttd3.tau"]), norm, opt), (m, s0)

    def update(state: FastTD3State, batch: Batch, r_max: jax.Array, key: jax.Array):
        """One update group: P critic updates (each on B transitions, each followed by the
        target's Polyak step) under one `lax.scan`, then one actor update on the last batch
        (module docstring)."""
        params, grouped, h = state.params, groups(batch), Hyper(state.hyper)
        carry = (params["critic"], state.target_critic, state.obs_norm, state.critic_opt_state)
        (critic, target, norm, critic_opt), (ms, s0s) = jax.lax.scan(
            lambda c, xs: critic_step(params["actor"], h, c, xs), carry,
            (grouped, jax.random.split(key, P)))  # fmt: skip
        last = jax.tree_util.tree_map(lambda x: x[-1], grouped)
        (_, (scale, pi_m)), grads = jax.value_and_grad(actor_loss, has_aux=True)(
            params["actor"], critic, state.scale, s0s[-1], last.action[0], last.episode_return,
            sirl_reference(r_max), h["sirl.beta"])  # fmt: skip
        upd, actor_opt = adamw(h, "actor").update(grads, state.actor_opt_state, params["actor"])
        params = {**params, "actor": optax.apply_updates(params["actor"], upd), "critic": critic}
        if fc.actor_ema > 0:
            params["actor_ema"] = polyak(params["actor_ema"], params["actor"], fc.actor_ema)
        new_state = FastTD3State(params, target, actor_opt, critic_opt, norm, scale, state.hyper)
        metrics = {k: jnp.mean(v) for k, v in ms.items()}
        return new_state, {**metrics, **pi_m, "actor_grad_norm": optax.tree.norm(grads)}

    def mean_action(state: FastTD3State, obs):
        """The acting actor's action: the averaged one when kept, else the trained one."""
        p = state.params["actor_ema" if fc.actor_ema > 0 else "actor"]
        return actor.apply({"params": p}, normalize(state.obs_norm, obs))

    def act(state: FastTD3State, noise: NoiseState, obs, first, key):
        """The actor plus Gaussian noise of each env's std, redrawn at its first step."""
        k_std, k_eps = jax.random.split(key)
        h = Hyper(state.hyper)
        fresh = jax.random.uniform(k_std, noise.std.shape, minval=h["fasttd3.std_min"],
                                   maxval=h["fasttd3.std_max"])  # fmt: skip
        std = jnp.where(first[:, None], fresh, noise.std)
        mean = mean_action(state, obs)
        action = mean + jax.random.normal(k_eps, mean.shape) * std
        return jnp.clip(action, -1.0, 1.0), NoiseState(std)

    def plan(state, noise, obs, first, key, eval_mode: bool = False):
        if eval_mode:
            return mean_action(state, obs), noise
        return act(state, noise, obs, first, key)

    def act_policy(state, obs, key, eval_mode: bool = False):
        if eval_mode:
            return mean_action(state, obs)
        first = jnp.ones(obs.shape[:1], bool)
        return act(state, init_noise(obs.shape[0]), obs, first, key)[0]

    def init_noise(num_envs: int) -> NoiseState:
        return NoiseState(jnp.zeros((num_envs, 1), jnp.float32))

    return Agent(cfg=cfg, obs_size=obs_size, action_size=A, episode_length=episode_length,
                 success_bar=success_bar, discount=fc.gamma, iterations=0, init=init,
                 update=update, sirl_reference=sirl_reference, init_planner=init_noise,
                 plan=plan, act_policy=act_policy, act=act)  # fmt: skip
