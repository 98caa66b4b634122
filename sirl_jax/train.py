"""`make_train`: the whole TD-MPC2/TDMPBC training step as one pure, jittable function.

E vectorised envs, the agent (MPPI planner + learner) and one device-resident replay buffer
share a `TrainState`. `Train.step` runs K vectorised env steps under one `lax.scan`; each one:

  1. acts: uniform random actions until planning starts, then MPPI (or the policy prior when
     `agent.mpc` is False), with a per-env warm start reset at each env's first step;
  2. steps the E envs (auto-reset, `final_obs` kept) and adds E transitions to the buffer;
  3. runs the owed gradient updates in one `fori_loop` with a traced trip count: none in the
     seed phase; `pretrain_updates` at once when the seed phase ends (spec §3.7); afterwards
     E * utd per step, a fractional remainder carried in `update_debt` (spec §4).

The caller jits `step` with `donate_argnums=0` (the buffer is updated in place) and may
`jax.vmap` `init`/`step`/`evaluate` over keys to train S seeds in one program. Under `vmap`
the acting `lax.cond` becomes a select (the planner also runs during the seed phase, results
unchanged) and the update loop runs the largest trip count over seeds with masking.

Shape letters: S seeds, E envs, K env steps per chunk, O observation, A action.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from sirl_jax.agent import Agent, AgentState, PlannerState, make_agent
from sirl_jax.buffer import Buffer, BufferState, make_buffer
from sirl_jax.config import Config
from sirl_jax.envs.base import Env, EnvState, VecEnv
from sirl_jax.envs.registry import TASKS, TaskSpec
from sirl_jax.evaluate import make_evaluate


@struct.dataclass
class TrainState:
    """Everything a run carries between jitted calls (add a leading [S] axis for seeds).

    Attributes:
      agent: networks, optimiser states, target Qs, running Q scale.
      planner: per-env MPPI warm start [E, H, A].
      env: EnvState [E] of the vectorised envs (auto-reset, episode returns).
      buffer: the replay buffer.
      key: PRNG key for the next chunk.
      env_steps: [] int32 transitions so far, summed over envs.
      updates: [] int32 gradient updates so far.
      update_debt: [] float32 fractional updates owed (utd * E not an integer).
      planning: [] bool the seed phase and pretraining are over; the agent acts.
      episodes: [] int32 episodes finished so far (all envs).
    """

    agent: AgentState
    planner: PlannerState
    env: EnvState
    buffer: BufferState
    key: jax.Array
    env_steps: jax.Array
    updates: jax.Array
    update_debt: jax.Array
    planning: jax.Array
    episodes: jax.Array


@dataclasses.dataclass(frozen=True)
class Train:
    """The pure functions of a run plus the static facts a shell needs.

    Attributes:
      init: (key) -> TrainState.
      step: (TrainState) -> (TrainState, metrics): K env steps and their updates; metrics
        is a flat dict of [] arrays (see `make_train`).
      evaluate: (TrainState, key) -> metrics of `eval_episodes` fresh episodes, planner and
        policy prior in eval mode.
      steps_per_call: K * E transitions per `step`.
      seed_steps: transitions of random acting before planning.
      pretrain_updates: updates run at once when the seed phase ends.
    """

    config: Config
    env: Env
    vec_env: VecEnv
    agent: Agent
    buffer: Buffer
    init: Callable[[jax.Array], TrainState]
    step: Callable[[TrainState], tuple[TrainState, dict[str, jax.Array]]]
    evaluate: Callable[[TrainState, jax.Array], dict[str, jax.Array]]
    steps_per_call: int
    seed_steps: int
    pretrain_updates: int
    return_ref: str


def load_task(name: str) -> TaskSpec:
    """The registry spec of a task id/alias, registering optional task families on demand."""
    from sirl_jax.envs import classic  # noqa: F401  (registers `pendulum`)
    from sirl_jax.envs.playground_adapter import is_playground_task, register_playground_task

    if is_playground_task(name):
        return register_playground_task(name)
    if name not in TASKS and importlib.util.find_spec("sirl_jax.envs.tasks") is not None:
        importlib.import_module("sirl_jax.envs.tasks")
    return TASKS.resolve(name)


def make_env(name: str) -> Env:
    """Builds the (unbatched) environment of a task."""
    return load_task(name).factory()


def _update_metric_names(agent: Agent, buffer: Buffer) -> tuple[str, ...]:
    shapes = jax.eval_shape(
        lambda k: agent.update(agent.init(k), buffer.sample(buffer.init(), k), k)[1],
        jax.random.PRNGKey(0),
    )
    return tuple(sorted(shapes))


def make_train(config: Config, env: Env) -> Train:
    """Builds the train functions for `config` on the unbatched `env`.

    Metrics of `step` (all [] arrays, per chunk): env_steps, updates, planning (0/1),
    episode/{return,length,count,terminated} (means over episodes finished in the chunk, NaN
    if none), reward (mean step reward), env/<term> (mean reward terms), train/<loss> (mean
    over the chunk's updates, NaN if none), train/num_updates, r_max (-inf before the first
    recorded episode), return_ref (the G the updates used), buffer/{episodes,transitions},
    nonfinite_obs (env steps whose s_{t+1} has a NaN/inf), nonfinite_loss (updates with a
    non-finite metric). A shell should stop when either count is non-zero.
    """
    tc, ac = config.train, config.agent
    config.validate_for_task(env.episode_length, env.success_bar)
    e, k_steps = tc.num_envs, tc.chunk_steps
    vec = VecEnv(env, e)
    o, a = env.observation_size, env.action_size
    agent = make_agent(ac, obs_size=o, action_size=a, episode_length=env.episode_length)
    discount = agent.discount if ac.sirl.return_kind == "discounted" else 1.0
    buffer = make_buffer(
        tc.capacity, e, o, a, ac.horizon, ac.batch_size, discount=discount, rmax_mode="in_buffer"
    )
    seed_steps = tc.resolved_seed_steps(env.episode_length)
    pretrain_updates = tc.pretrain_updates(env.episode_length)
    use_target = ac.sirl.g_source == "target"
    success_bar = jnp.float32(env.success_bar if env.success_bar is not None else jnp.nan)
    update_names = _update_metric_names(agent, buffer)
    term_names = tuple(env.metric_names())

    def init(key: jax.Array) -> TrainState:
        key_agent, key_env, key_run = jax.random.split(key, 3)
        zero = jnp.zeros((), jnp.int32)
        return TrainState(
            agent=agent.init(key_agent),
            planner=agent.init_planner(e),
            env=vec.reset(key_env),
            buffer=buffer.init(),
            key=key_run,
            env_steps=zero,
            updates=zero,
            update_debt=jnp.zeros((), jnp.float32),
            planning=jnp.zeros((), bool),
            episodes=zero,
        )

    def act(state: TrainState, key: jax.Array) -> tuple[jax.Array, PlannerState]:
        def explore(_):
            return jax.random.uniform(key, (e, a), minval=-1.0, maxval=1.0), state.planner

        def exploit(_):
            if ac.mpc:
                return agent.plan(state.agent, state.planner, state.env.obs, state.env.first, key)
            return agent.act_policy(state.agent, state.env.obs, key), state.planner

        return jax.lax.cond(state.planning, exploit, explore, None)

    def run_updates(agent_state, buf, num, key):
        """`num` (traced) updates on fresh batches; returns summed metrics and a NaN count."""

        def body(i, carry):
            agent_state, sums, bad = carry
            key_sample, key_update = jax.random.split(jax.random.fold_in(key, i))
            batch = buffer.sample(buf, key_sample)
            if use_target:
                batch = batch.replace(return_ref=success_bar)
            agent_state, m = agent.update(agent_state, batch, key_update)
            means = [jnp.mean(m[n]) for n in update_names]
            finite = jnp.isfinite(sum(means))  # a NaN or inf in any metric makes the sum one
            sums = {n: sums[n] + v for n, v in zip(update_names, means, strict=True)}
            return agent_state, sums, bad + (~finite).astype(jnp.int32)

        sums0 = {n: jnp.zeros((), jnp.float32) for n in update_names}
        return jax.lax.fori_loop(0, num, body, (agent_state, sums0, jnp.zeros((), jnp.int32)))

    def env_step(carry, _):
        state, acc = carry
        key, key_act, key_update = jax.random.split(state.key, 3)
        action, planner = act(state, key_act)
        env_state = vec.step(state.env, action)
        buf = buffer.add(
            state.buffer,
            state.env.obs,
            action,
            env_state.reward,
            env_state.final_obs,
            env_state.terminated,
            env_state.truncated,
        )
        env_steps = state.env_steps + e
        can_sample = buffer.can_sample(buf)
        start_now = ~state.planning & (env_steps >= seed_steps) & can_sample
        owed = state.update_debt + jnp.where(state.planning, jnp.float32(e * tc.utd), 0.0)
        regular = jnp.floor(owed)
        num = jnp.where(start_now, pretrain_updates, regular.astype(jnp.int32))
        num = jnp.where(can_sample, num, 0)
        agent_state, sums, bad = run_updates(state.agent, buf, num, key_update)

        done = env_state.terminated | env_state.truncated
        ref = success_bar if use_target else buffer.r_max(buf)
        acc = {
            "ret": acc["ret"] + jnp.sum(jnp.where(done, env_state.last_return, 0.0)),
            "len": acc["len"] + jnp.sum(jnp.where(done, env_state.last_length, 0)),
            "count": acc["count"] + jnp.sum(done, dtype=jnp.int32),
            "term": acc["term"] + jnp.sum(env_state.terminated, dtype=jnp.int32),
            "reward": acc["reward"] + jnp.sum(env_state.reward),
            "terms": {n: acc["terms"][n] + jnp.sum(env_state.metrics[n]) for n in term_names},
            "upd": {n: acc["upd"][n] + sums[n] for n in update_names},
            "num_updates": acc["num_updates"] + num,
            "nonfinite_obs": acc["nonfinite_obs"]
            + jnp.sum(~jnp.all(jnp.isfinite(env_state.final_obs), axis=-1), dtype=jnp.int32),
            "nonfinite_loss": acc["nonfinite_loss"] + bad,
            "return_ref": ref,
        }
        state = TrainState(
            agent=agent_state,
            planner=planner,
            env=env_state,
            buffer=buf,
            key=key,
            env_steps=env_steps,
            updates=state.updates + num,
            update_debt=jnp.where(state.planning, owed - regular, 0.0),
            planning=state.planning | start_now,
            episodes=state.episodes + jnp.sum(done, dtype=jnp.int32),
        )
        return (state, acc), None

    def step(state: TrainState) -> tuple[TrainState, dict[str, jax.Array]]:
        zf, zi = jnp.zeros((), jnp.float32), jnp.zeros((), jnp.int32)
        acc0 = {
            "ret": zf,
            "len": zi,
            "count": zi,
            "term": zi,
            "reward": zf,
            "terms": {n: zf for n in term_names},
            "upd": {n: zf for n in update_names},
            "num_updates": zi,
            "nonfinite_obs": zi,
            "nonfinite_loss": zi,
            "return_ref": zf,
        }
        (state, acc), _ = jax.lax.scan(env_step, (state, acc0), None, length=k_steps)
        return state, _chunk_metrics(state, acc)

    def _chunk_metrics(state: TrainState, acc) -> dict[str, jax.Array]:
        count = acc["count"].astype(jnp.float32)
        per_episode = jnp.where(count > 0, 1.0 / jnp.maximum(count, 1.0), jnp.nan)
        nu = acc["num_updates"].astype(jnp.float32)
        per_update = jnp.where(nu > 0, 1.0 / jnp.maximum(nu, 1.0), jnp.nan)
        n_steps = jnp.float32(k_steps * e)
        metrics = {
            "env_steps": state.env_steps,
            "updates": state.updates,
            "planning": state.planning.astype(jnp.float32),
            "episode/return": acc["ret"] * per_episode,
            "episode/length": acc["len"].astype(jnp.float32) * per_episode,
            "episode/count": acc["count"],
            "episode/terminated": acc["term"],
            "reward": acc["reward"] / n_steps,
            "train/num_updates": acc["num_updates"],
            "r_max": buffer.r_max(state.buffer),
            "return_ref": acc["return_ref"],
            "buffer/episodes": buffer.num_episodes(state.buffer),
            "buffer/transitions": buffer.num_transitions(state.buffer),
            "nonfinite_obs": acc["nonfinite_obs"],
            "nonfinite_loss": acc["nonfinite_loss"],
        }
        metrics.update({f"env/{n}": v / n_steps for n, v in acc["terms"].items()})
        metrics.update({f"train/{n}": v * per_update for n, v in acc["upd"].items()})
        return metrics

    evaluate = make_evaluate(env, agent, tc.eval_episodes, buffer)
    return Train(
        config=config,
        env=env,
        vec_env=vec,
        agent=agent,
        buffer=buffer,
        init=init,
        step=step,
        evaluate=evaluate,
        steps_per_call=k_steps * e,
        seed_steps=seed_steps,
        pretrain_updates=pretrain_updates,
        return_ref="success_bar" if use_target else "r_max",
    )
