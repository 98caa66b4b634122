"""`make_train`: the whole TD-MPC2/TDMPBC training step as one pure, jittable function.

E vectorised envs, the agent (MPPI planner + learner) and one device-resident replay buffer
share a `TrainState`. `Train.step` runs K vectorised env steps under one `lax.scan`; each one:

  1. acts (`Train.act`): uniform random actions until planning starts, then `Agent.act`:
     TD-MPC2's MPPI (or its policy prior when `agent.mpc` is False) with a per-env warm start,
     or FastTD3's actor with per-env exploration noise; either resets its per-env acting
     state at each env's first step;
  2. steps the E envs (auto-reset, `final_obs` kept) and adds E transitions to the buffer,
     but none from an env whose physics blew up (`VecEnv` reset it; its episode is dropped);
  3. runs the updates `update_schedule` owes (`Train.update` each) in one `fori_loop` with a
     traced trip count.

The caller jits `step` with `donate_argnums=0` (the buffer is updated in place) and may
`jax.vmap` `init`/`step`/`evaluate` over keys to train S seeds in one program. Under `vmap`
the acting `lax.cond` becomes a select (the planner also runs during the seed phase, results
unchanged) and the update loop runs the largest trip count over seeds with masking.

Shape letters: S seeds, E envs, K env steps per chunk, O observation, A action.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from sirl_jax.agent import Agent, AgentState, PlannerState, make_agent
from sirl_jax.buffer import Buffer, BufferState, make_buffer
from sirl_jax.config import Config
from sirl_jax.envs.base import Env, EnvState, VecEnv
from sirl_jax.evaluate import make_evaluate
from sirl_jax.types import Batch


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


def update_schedule(
    planning: jax.Array,
    env_steps: jax.Array,
    debt: jax.Array,
    can_sample: jax.Array,
    *,
    updates_per_step: float,
    seed_steps: int,
    pretrain_updates: int,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The updates owed after one vectorised env step (spec §3.7, §4).

    Seed phase: none. The step that reaches `seed_steps` transitions with a sampleable buffer
    starts planning and owes `pretrain_updates` (TD-MPC2's pretraining). Afterwards each step
    owes `updates_per_step` (`Train.updates_per_step`), the fractional part carried in `debt`.
    Nothing is owed while the buffer cannot sample.

    Args:
      planning: [] bool planning had started before this step.
      env_steps: [] int transitions after this step (all envs).
      debt: [] float fractional updates carried from earlier steps.
      can_sample: [] bool the buffer holds a sampleable episode after this step.

    Returns:
      (updates to run now [] int32, debt to carry [] float32, planning after this step [] bool).
    """
    start_now = ~planning & (env_steps >= seed_steps) & can_sample
    owed = debt + jnp.where(planning, jnp.float32(updates_per_step), 0.0)
    regular = jnp.floor(owed)
    num = jnp.where(start_now, pretrain_updates, regular.astype(jnp.int32))
    num = jnp.where(can_sample, num, 0).astype(jnp.int32)
    new_debt = jnp.where(planning, owed - regular, 0.0).astype(jnp.float32)
    return num, new_debt, planning | start_now


@struct.dataclass
class ChunkStats:
    """Sums over one chunk's env steps and updates; `finalize` turns them into metrics."""

    episode_return: jax.Array  # [] summed over finished episodes
    episode_length: jax.Array
    episodes: jax.Array  # [] int32 episodes finished
    terminated: jax.Array  # [] int32 of those, ended by the task's termination
    reward: jax.Array  # [] summed over env steps
    terms: dict  # reward term -> [] sum over env steps
    losses: dict  # update metric -> [] sum over updates
    num_updates: jax.Array
    blowups: jax.Array  # [] int32 env steps whose physics blew up (env reset, step dropped)
    nonfinite_loss: jax.Array  # [] int32 updates with a non-finite metric

    @classmethod
    def zeros(cls, term_names: tuple[str, ...], loss_names: tuple[str, ...]) -> ChunkStats:
        zf, zi = jnp.zeros((), jnp.float32), jnp.zeros((), jnp.int32)
        return cls(zf, zi, zi, zi, zf, {n: zf for n in term_names},
                   {n: zf for n in loss_names}, zi, zi, zi)  # fmt: skip

    def add(self, env: EnvState, loss_sums: dict, num: jax.Array, bad: jax.Array) -> ChunkStats:
        """Adds one vectorised env step (`env` after it) and the updates run after it."""
        done = env.terminated | env.truncated
        i32 = jnp.int32
        return ChunkStats(
            episode_return=self.episode_return + jnp.sum(jnp.where(done, env.last_return, 0.0)),
            episode_length=self.episode_length + jnp.sum(jnp.where(done, env.last_length, 0)),
            episodes=self.episodes + jnp.sum(done, dtype=i32),
            terminated=self.terminated + jnp.sum(env.terminated, dtype=i32),
            reward=self.reward + jnp.sum(env.reward),
            terms={n: v + jnp.sum(env.metrics[n]) for n, v in self.terms.items()},
            losses={n: v + loss_sums[n] for n, v in self.losses.items()},
            num_updates=self.num_updates + num,
            blowups=self.blowups + jnp.sum(env.blowup, dtype=i32),
            nonfinite_loss=self.nonfinite_loss + bad,
        )

    def finalize(self, env_steps_in_chunk: int) -> dict[str, jax.Array]:
        """Per-episode, per-step and per-update means (NaN where the chunk had none)."""
        count = self.episodes.astype(jnp.float32)
        per_episode = jnp.where(count > 0, 1.0 / jnp.maximum(count, 1.0), jnp.nan)
        nu = self.num_updates.astype(jnp.float32)
        per_update = jnp.where(nu > 0, 1.0 / jnp.maximum(nu, 1.0), jnp.nan)
        n_steps = jnp.float32(env_steps_in_chunk)
        metrics = {
            "episode/return": self.episode_return * per_episode,
            "episode/length": self.episode_length.astype(jnp.float32) * per_episode,
            "episode/count": self.episodes,
            "episode/terminated": self.terminated,
            "reward": self.reward / n_steps,
            "train/num_updates": self.num_updates,
            "env/blowups": self.blowups,
            "nonfinite_loss": self.nonfinite_loss,
        }
        metrics.update({f"env/{n}": v / n_steps for n, v in self.terms.items()})
        metrics.update({n if "/" in n else f"train/{n}": v * per_update
                        for n, v in self.losses.items()})  # fmt: skip
        return metrics


@dataclasses.dataclass(frozen=True)
class Train:
    """The pure functions of a run plus the static facts a shell needs.

    Attributes:
      init: (key) -> TrainState.
      step: (TrainState) -> (TrainState, metrics): K env steps and their updates; metrics
        is a flat dict of [] arrays (see `make_train`).
      act: (TrainState, key) -> (actions [E, A], PlannerState): step 1 of the env step.
      update: (AgentState, BufferState, key) -> (AgentState, metrics): one gradient update
        on a fresh batch, with the buffer's R_max passed to the agent.
      evaluate: (TrainState, key) -> metrics of `eval_episodes` fresh episodes, planner and
        policy prior in eval mode.
      seed_steps: transitions of random acting before planning.
      pretrain_updates: updates run at once when the seed phase ends.
      updates_per_step: `update` calls owed per vectorised env step once acting: TD-MPC2's
        num_envs * utd, FastTD3's num_updates / policy_frequency.
    """

    config: Config
    env: Env
    vec_env: VecEnv
    agent: Agent
    buffer: Buffer
    init: Callable[[jax.Array], TrainState]
    step: Callable[[TrainState], tuple[TrainState, dict[str, jax.Array]]]
    act: Callable[[TrainState, jax.Array], tuple[jax.Array, PlannerState]]
    update: Callable[[AgentState, BufferState, jax.Array], tuple[AgentState, dict]]
    evaluate: Callable[[TrainState, jax.Array], dict[str, jax.Array]]
    seed_steps: int
    pretrain_updates: int
    updates_per_step: float


def make_train(config: Config, env: Env, *,
               constrain_batch: Callable[[Batch], Batch] | None = None) -> Train:  # fmt: skip
    """Builds the train functions for `config` on the unbatched `env`.

    `constrain_batch` is applied to every sampled batch before the update (identity if None);
    `sirl_jax.sharding.batch_constraint` splits it over devices.

    Raises ValueError when the config does not fit the task (episode length, replay capacity,
    a success bar for `g_source="target"`).

    Metrics of `step` (all [] arrays, per chunk): env_steps, updates, planning (0/1),
    episode/{return,length,count,terminated} (means over episodes finished in the chunk, NaN
    if none), reward (mean step reward), env/<term> (mean reward terms), train/<loss> and
    sirl/clamped_fraction (means over the chunk's updates, NaN if none), train/num_updates,
    r_max (-inf before the first recorded episode), sirl/reference (the G of the next update),
    buffer/episodes, env/blowups (env steps whose physics went non-finite: `VecEnv` reset that
    env and the transition was not stored), nonfinite_loss (updates with a non-finite metric).
    A shell should stop when nonfinite_loss is non-zero or blow-ups exceed its tolerated rate.
    """
    tc, ac = config.train, config.agent
    config.validate_for_task(env.episode_length)
    e = tc.num_envs
    vec = VecEnv(env, e)
    o, a = env.observation_size, env.action_size
    agent = make_agent(ac, o, a, env.episode_length, env.success_bar)
    discount = agent.discount if ac.sirl.return_kind == "discounted" else 1.0
    sampling = ac.fasttd3.replay_sampling if ac.kind == "fasttd3" else "episode"
    buffer = make_buffer(tc.capacity, e, o, a, ac.window, ac.sample_size, discount=discount,
                         rmax_mode=ac.sirl.rmax_mode, sampling=sampling)  # fmt: skip
    tdmpc2 = ac.kind == "tdmpc2"  # FastTD3 has no pretraining and its own update rate
    schedule = dict(
        updates_per_step=e * tc.utd if tdmpc2 else ac.fasttd3.updates_per_step,
        seed_steps=tc.resolved_seed_steps(env.episode_length),
        pretrain_updates=tc.pretrain_updates(env.episode_length) if tdmpc2 else 0,
    )

    def init(key: jax.Array) -> TrainState:
        key_agent, key_env, key_run = jax.random.split(key, 3)
        zero = jnp.zeros((), jnp.int32)
        return TrainState(agent=agent.init(key_agent), planner=agent.init_planner(e),
                          env=vec.reset(key_env), buffer=buffer.init(), key=key_run,
                          env_steps=zero, updates=zero, update_debt=jnp.zeros((), jnp.float32),
                          planning=jnp.zeros((), bool))  # fmt: skip

    def act(state: TrainState, key: jax.Array) -> tuple[jax.Array, PlannerState]:
        def explore(_):
            return jax.random.uniform(key, (e, a), minval=-1.0, maxval=1.0), state.planner

        def exploit(_):
            return agent.act(state.agent, state.planner, state.env.obs, state.env.first, key)

        return jax.lax.cond(state.planning, exploit, explore, None)

    def update(agent_state: AgentState, buf: BufferState, key: jax.Array):
        key_sample, key_update = jax.random.split(key)
        batch = buffer.sample(buf, key_sample)
        if constrain_batch is not None:
            batch = constrain_batch(batch)
        return agent.update(agent_state, batch, buffer.r_max(buf), key_update)

    loss_names = tuple(sorted(jax.eval_shape(
        lambda k: update(agent.init(k), buffer.init(), k)[1], jax.random.PRNGKey(0))))  # fmt: skip

    def run_updates(agent_state, buf, num, key):
        """`num` (traced) updates; returns the agent, summed metrics and a non-finite count."""

        def body(i, carry):
            agent_state, sums, bad = carry
            agent_state, m = update(agent_state, buf, jax.random.fold_in(key, i))
            means = [jnp.mean(m[n]) for n in loss_names]
            finite = jnp.isfinite(sum(means))  # a NaN or inf in any metric makes the sum one
            sums = {n: sums[n] + v for n, v in zip(loss_names, means, strict=True)}
            return agent_state, sums, bad + (~finite).astype(jnp.int32)

        sums0 = {n: jnp.zeros((), jnp.float32) for n in loss_names}
        return jax.lax.fori_loop(0, num, body, (agent_state, sums0, jnp.zeros((), jnp.int32)))

    def env_step(carry, _):
        state, stats = carry
        key, key_act, key_update = jax.random.split(state.key, 3)
        action, planner = act(state, key_act)
        env_state = vec.step(state.env, action)
        buf = buffer.add(state.buffer, state.env.obs, action, env_state.reward, env_state.final_obs,
                         env_state.terminated, env_state.truncated, env_state.blowup)  # fmt: skip
        env_steps = state.env_steps + e
        num, debt, planning = update_schedule(
            state.planning, env_steps, state.update_debt, buffer.can_sample(buf), **schedule
        )
        agent_state, sums, bad = run_updates(state.agent, buf, num, key_update)
        state = TrainState(agent=agent_state, planner=planner, env=env_state, buffer=buf,
                           key=key, env_steps=env_steps, updates=state.updates + num,
                           update_debt=debt, planning=planning)  # fmt: skip
        return (state, stats.add(env_state, sums, num, bad)), None

    def step(state: TrainState) -> tuple[TrainState, dict[str, jax.Array]]:
        stats = ChunkStats.zeros(tuple(env.metric_names()), loss_names)
        (state, stats), _ = jax.lax.scan(env_step, (state, stats), None, length=tc.chunk_steps)
        r_max = buffer.r_max(state.buffer)
        return state, {
            **stats.finalize(tc.steps_per_call),
            "env_steps": state.env_steps,
            "updates": state.updates,
            "planning": state.planning.astype(jnp.float32),
            "r_max": r_max,
            "sirl/reference": agent.sirl_reference(r_max),
            "buffer/episodes": buffer.num_episodes(state.buffer),
        }

    return Train(config=config, env=env, vec_env=vec, agent=agent, buffer=buffer, init=init,
                 step=step, act=act, update=update,
                 evaluate=make_evaluate(env, agent, tc.eval_episodes, buffer),
                 seed_steps=schedule["seed_steps"],
                 pretrain_updates=schedule["pretrain_updates"],
                 updates_per_step=schedule["updates_per_step"])  # fmt: skip
