"""`make_tdmpc2`: the TD-MPC2/TDMPBC agent as pure functions over `AgentState` (spec §2.4, §3)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import optax
from flax import struct

from sirl_jax.agent import losses
from sirl_jax.agent.config import AgentConfig
from sirl_jax.agent.hyper import Hyper
from sirl_jax.agent.math import discount_from_episode_length
from sirl_jax.agent.networks import init_params
from sirl_jax.agent.planner import PlannerModel, PlannerState, make_planner
from sirl_jax.agent.world_model import make_world_model
from sirl_jax.types import Batch

WM_KEYS = ("encoder", "dynamics", "reward", "qs")
"""World-model params (one optimiser, one global clip); 'termination' is added when episodic."""


def wm_keys(cfg: AgentConfig) -> tuple[str, ...]:
    """The params entries trained by the world-model optimiser for this config."""
    return WM_KEYS + (("termination",) if cfg.episodic else ())


@struct.dataclass
class AgentState:
    """params: {'encoder', 'dynamics', 'reward', 'policy', 'qs'} (+ 'termination' if episodic);
    target_qs: Polyak copy of 'qs';
    wm_opt_state / pi_opt_state: Adam states; scale: [] running Q scale S;
    hyper: the run's per-run scalars (`sirl_jax.agent.hyper`)."""

    params: dict
    target_qs: dict
    wm_opt_state: optax.OptState
    pi_opt_state: optax.OptState
    scale: jax.Array
    hyper: dict


@dataclasses.dataclass(frozen=True)
class Agent:
    """Static agent description plus its pure functions (none of them jitted): the seam both
    learners (`cfg.kind`: TD-MPC2 here, FastTD3 in `fasttd3.py`) present to the train step,
    evaluation, render and export. `plan` is MPPI for TD-MPC2; FastTD3 has no planner and its
    `plan` is its actor (noisy unless eval_mode), which evaluation does not run twice
    (`cfg.plans`)."""

    cfg: AgentConfig
    obs_size: int
    action_size: int
    episode_length: int
    success_bar: float | None
    discount: float
    iterations: int
    init: Callable  # (key) -> AgentState
    update: Callable  # (AgentState, Batch, r_max [], key) -> (AgentState, metrics)
    sirl_reference: Callable  # (r_max []) -> G [] of the self-imitative weight
    init_planner: Callable  # (num_envs) -> the per-env acting state (MPPI warm start, noise)
    plan: Callable  # (state, acting state, obs[E, O], first[E], key, eval_mode) -> (a, acting)
    act_policy: Callable  # (state, obs[E, O], key, eval_mode) -> action[E, A]
    act: Callable  # (state, acting state, obs, first, key) -> (a[E, A], acting): training's


def _wm_optimizer(cfg: AgentConfig, h: Hyper | None = None) -> optax.GradientTransformation:
    """One global-norm clip over all world-model params, then Adam; encoder lr x enc_lr_scale.
    h: the run's traced rates (`state.hyper`); None: `cfg`'s (the optimiser state is the same)."""
    h = Hyper.of(cfg, h)

    def labels(params):
        return {
            k: jax.tree_util.tree_map(lambda _, k=k: "enc" if k == "encoder" else "rest", v)
            for k, v in params.items()
        }

    return optax.chain(
        optax.clip_by_global_norm(cfg.grad_clip_norm),
        optax.multi_transform(
            {"enc": optax.adam(h["enc_lr"]), "rest": optax.adam(h["lr"])}, labels
        ),
    )


def polyak(target, online, tau):
    """target <- (1 - tau) * target + tau * online, leaf-wise."""
    return jax.tree_util.tree_map(lambda t, o: (1.0 - tau) * t + tau * o, target, online)


def check_sizes(cfg: AgentConfig, obs_size: int, action_size: int, episode_length: int,
                success_bar: float | None) -> None:  # fmt: skip
    """The checks every learner makes on its static sizes and on G's source."""
    if cfg.sirl.enabled and cfg.sirl.g_source == "target" and success_bar is None:
        raise ValueError(
            "agent.sirl.g_source='target' is invalid for a task without a success bar; "
            "allowed: 'rmax'"
        )
    for name, v in (
        ("obs_size", obs_size),
        ("action_size", action_size),
        ("episode_length", episode_length),
    ):
        if v < 1:
            raise ValueError(f"{name}={v} is invalid; allowed: an int >= 1")


def make_sirl_reference(cfg: AgentConfig, success_bar: float | None) -> Callable:
    """(r_max []) -> G [] of the self-imitative weight: the buffer's R_max, or the success bar
    (`cfg.sirl.g_source`)."""

    def sirl_reference(r_max: jax.Array) -> jax.Array:
        if cfg.sirl.g_source == "target":  # NaN only when the term is off and there is no bar
            return jnp.float32(jnp.nan if success_bar is None else success_bar)
        return jnp.asarray(r_max, jnp.float32)

    return sirl_reference


def make_tdmpc2(
    cfg: AgentConfig,
    obs_size: int,
    action_size: int,
    episode_length: int,
    success_bar: float | None = None,
) -> Agent:
    """Builds TD-MPC2 (+ TDMPBC) for static sizes; gamma, MPPI iterations and G's source are
    fixed here (`factory.make_agent` picks it or FastTD3 by `cfg.kind`).

    success_bar: the task's R_target; required when `cfg.sirl.g_source == "target"`.
    """
    check_sizes(cfg, obs_size, action_size, episode_length, success_bar)
    discount = (
        cfg.discount
        if cfg.discount is not None
        else discount_from_episode_length(
            episode_length, cfg.discount_denom, cfg.discount_min, cfg.discount_max
        )
    )
    iterations = cfg.iterations + (2 if action_size >= 20 else 0)
    env_chunk = cfg.plan_env_chunk
    if env_chunk is None:  # measured: sequential envs are faster than one big vmap on CPU
        env_chunk = 1 if jax.default_backend() == "cpu" else 0
    wm = make_world_model(cfg, action_size)
    keys = wm_keys(cfg)

    def pi_optimizer(h: Hyper) -> optax.GradientTransformation:
        return optax.chain(optax.clip_by_global_norm(cfg.grad_clip_norm),
                           optax.adam(h["lr"], eps=cfg.pi_adam_eps))  # fmt: skip

    planner = make_planner(
        cfg,
        action_size,
        discount,
        iterations,
        PlannerModel(
            encode=wm.encode,
            next=wm.next,
            reward=wm.reward,
            pi_sample=lambda p, z, k: wm.pi(p, z, k).action,
            q_avg=lambda p, z, a, k: wm.q_pair(p["qs"], z, a, k, "avg", None),
            termination=wm.termination_logit,  # None unless episodic
        ),
        env_chunk,
    )

    def init(key: jax.Array) -> AgentState:
        params = init_params(cfg, obs_size, action_size, key)
        wm_params, h = {k: params[k] for k in keys}, Hyper.of(cfg)
        return AgentState(
            params=params,
            target_qs=jax.tree_util.tree_map(jnp.copy, params["qs"]),
            wm_opt_state=_wm_optimizer(cfg, h).init(wm_params),
            pi_opt_state=pi_optimizer(h).init(params["policy"]),
            scale=jnp.ones((), jnp.float32),
            hyper=h.hyper,
        )

    sirl_reference = make_sirl_reference(cfg, success_bar)

    def update(
        state: AgentState, batch: Batch, r_max: jax.Array, key: jax.Array
    ) -> tuple[AgentState, dict]:
        """One gradient step: world model; policy on detached latents and updated Qs; Polyak.

        r_max: [] the replay buffer's R_max (`Buffer.r_max`); G follows `cfg.sirl.g_source`.
        """
        k_wm, k_pi = jax.random.split(key)
        h = Hyper(state.hyper)
        wm_params = {k: state.params[k] for k in keys}
        pi_params = state.params["policy"]
        grad_fn = jax.value_and_grad(
            lambda p: losses.world_model_loss(
                wm, cfg, discount, p, pi_params, state.target_qs, batch, k_wm, h
            ),
            has_aux=True,
        )
        (wm_loss, (zs, wm_metrics)), wm_grads = grad_fn(wm_params)
        upd, wm_opt_state = _wm_optimizer(cfg, h).update(wm_grads, state.wm_opt_state, wm_params)
        wm_params = optax.apply_updates(wm_params, upd)

        pi_grad_fn = jax.value_and_grad(
            lambda p: losses.policy_loss(
                wm,
                cfg,
                p,
                losses.sg(wm_params["qs"]),
                losses.sg(zs),
                state.scale,
                batch,
                sirl_reference(r_max),
                k_pi,
                h,
            ),
            has_aux=True,
        )
        (pi_loss, (scale, pi_metrics)), pi_grads = pi_grad_fn(pi_params)
        upd, pi_opt_state = pi_optimizer(h).update(pi_grads, state.pi_opt_state, pi_params)
        pi_params = optax.apply_updates(pi_params, upd)

        new_state = AgentState(
            params={**wm_params, "policy": pi_params},
            target_qs=polyak(state.target_qs, wm_params["qs"], h["tau"]),
            wm_opt_state=wm_opt_state,
            pi_opt_state=pi_opt_state,
            scale=scale,
            hyper=state.hyper,
        )
        metrics = {
            **wm_metrics,
            **pi_metrics,
            "total_loss": wm_loss + pi_loss,
            "grad_norm": optax.tree.norm(wm_grads),
            "pi_grad_norm": optax.tree.norm(pi_grads),
        }
        return new_state, metrics

    def plan(
        state: AgentState, planner_state: PlannerState, obs, first, key, eval_mode: bool = False
    ):
        """MPPI actions [E, A] for obs [E, O]; first [E] resets that env's warm start."""
        return planner.plan(state.params, planner_state, obs, first, key, eval_mode)

    def act_policy(state: AgentState, obs, key, eval_mode: bool = False):
        """The policy prior alone: tanh(mu) in eval mode, a sample otherwise ([E, O] -> [E, A])."""
        z = wm.encode(state.params, obs)
        out = wm.pi(state.params, z, key)
        return out.mean_action if eval_mode else out.action

    def act(state: AgentState, planner_state: PlannerState, obs, first, key):
        """Training's actions: MPPI, or the policy prior when `cfg.mpc` is False."""
        if cfg.mpc:
            return plan(state, planner_state, obs, first, key)
        return act_policy(state, obs, key), planner_state

    return Agent(
        cfg=cfg,
        obs_size=obs_size,
        action_size=action_size,
        episode_length=episode_length,
        success_bar=success_bar,
        discount=discount,
        iterations=iterations,
        init=init,
        update=update,
        sirl_reference=sirl_reference,
        init_planner=planner.init,
        plan=plan,
        act_policy=act_policy,
        act=act,
    )
