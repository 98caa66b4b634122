"""The functional environment contract and the one auto-reset wrapper.

An `Env` is a set of pure functions over an `EnvState` pytree, in the spirit of
mujoco_playground's `MjxEnv`:

    state = env.reset(key)            # one episode start
    state = env.step(state, action)   # one control step, no reset, no time limit

`VecEnv` is the only place that vmaps over environments, counts steps, sets `truncated` at
`episode_length`, and resets finished episodes. Unlike the brax/playground auto-reset wrappers
it keeps the pre-reset observation in `final_obs`, so a learner can store the true s_{t+1}.
It also resets an env whose physics blew up (a non-finite qpos, qvel, observation or reward),
from that env's own key, and flags the step `blowup` so the learner drops the transition; the
other envs are untouched, bit for bit.

Shape letters: E envs, O observation size, A action size.
"""

from __future__ import annotations

import abc
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class EnvState:
    """State of one environment (add a leading [E] axis for a `VecEnv`).

    Attributes:
      physics: the simulator state (`mjx.Data` for MJX envs), or any pytree.
      task: task-specific state (maze stage, reach goal, ...), any pytree; `()` if none.
      obs: [O] float32 observation after the step (after the reset, if one happened).
      reward: [] float32 reward of the step.
      terminated: [] bool, the step ended the episode by a task termination (a fall).
      truncated: [] bool, the step hit the time limit without terminating.
      final_obs: [O] the observation the step produced, before any auto-reset. Equals `obs`
        when no reset happened. This is s_{t+1} for the learner.
      first: [] bool, `obs` is the first observation of an episode.
      step_count: [] int32 steps taken in the current episode.
      episode_return: [] float32 undiscounted return of the current episode so far.
      last_return: [] float32 return of the most recently finished episode (NaN before any).
      last_length: [] int32 length of the most recently finished episode (0 before any).
      metrics: dict of [] float32 per-step quantities to log (each reward term).
      key: PRNG key used for the next reset.
      blowup: [] bool, the step's physics went non-finite; the env was reset instead (`obs`,
        `final_obs` are the reset observation, `reward` and `metrics` zero, no episode ended).
    """

    physics: Any
    task: Any
    obs: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    final_obs: jax.Array
    first: jax.Array
    step_count: jax.Array
    episode_return: jax.Array
    last_return: jax.Array
    last_length: jax.Array
    metrics: dict[str, jax.Array]
    key: jax.Array
    blowup: jax.Array


class Env(abc.ABC):
    """A single, unbatched environment. Subclasses implement `reset` and `step`.

    `step` must set `obs`, `reward`, `terminated`, `physics`, `task` and `metrics`; the
    bookkeeping fields (`truncated`, `final_obs`, `first`, `step_count`, returns) belong to
    `VecEnv`. Use `init_state` to build a fresh state in `reset`.

    MJX envs set `mj_model` (the CPU `mujoco.MjModel` of their whole scene) so a rollout can be
    drawn with MuJoCo's renderer; `mjx_data(physics)` is the `mjx.Data` in their physics state.
    """

    mj_model: Any = None
    """The scene's `mujoco.MjModel` (None: the env cannot be rendered)."""
    control_dt: float = 0.02
    """Simulated seconds per control step (50 Hz: HumanoidBench and the pendulum)."""

    def mjx_data(self, physics: Any) -> Any:
        """The `mjx.Data` inside `EnvState.physics` (MJX envs: `physics` itself)."""
        return physics

    def physics_finite(self, physics: Any) -> jax.Array:
        """[] bool, the physics state is finite: qpos and qvel of `mjx_data(physics)`, or
        every float leaf of `physics` when it has no qpos/qvel."""
        data = self.mjx_data(physics)
        if hasattr(data, "qpos") and hasattr(data, "qvel"):
            leaves = [data.qpos, data.qvel]
        else:
            leaves = [x for x in jax.tree.leaves(physics) if jnp.issubdtype(x.dtype, jnp.inexact)]
        finite = jnp.ones((), bool)
        for x in leaves:
            finite &= jnp.all(jnp.isfinite(x))
        return finite

    @property
    @abc.abstractmethod
    def observation_size(self) -> int: ...

    @property
    @abc.abstractmethod
    def action_size(self) -> int: ...

    @property
    @abc.abstractmethod
    def episode_length(self) -> int:
        """Time limit in control steps (agent steps)."""

    @property
    def success_bar(self) -> float | None:
        """Episode return counted as success (HumanoidBench's R_target), if the task has one."""
        return None

    @abc.abstractmethod
    def reset(self, key: jax.Array) -> EnvState: ...

    @abc.abstractmethod
    def step(self, state: EnvState, action: jax.Array) -> EnvState: ...

    def reset_next(self, key: jax.Array, previous: EnvState) -> EnvState:
        """The start of the episode that follows `previous` in the same env (`VecEnv`'s
        auto-reset). Default: `reset(key)`. An env that reproduces state HumanoidBench keeps
        across resets (`Task.carry`) overrides it; `reset` stays a fresh env's first episode."""
        del previous
        return self.reset(key)

    def metric_names(self) -> tuple[str, ...]:
        """Names of the per-step metrics `step` reports (must match `reset`)."""
        return ()

    @property
    def physics_impl(self) -> str:
        """The MJX backend this env steps with: "jax" (the default) or "warp"."""
        return "jax"

    def with_physics(self, physics: Any) -> Env:
        """A copy that simulates with `physics` (`sirl_jax.envs.physics.Physics`: impl, worlds,
        Warp buffer margin). Default: an env that can only run MJX-JAX refuses."""
        raise ValueError(
            f"{type(self).__name__} cannot switch its physics, so it cannot run "
            f"impl={physics.impl!r}; allowed: impl='jax'"
        )


def init_state(
    physics: Any,
    obs: jax.Array,
    key: jax.Array,
    task: Any = (),
    metrics: dict[str, jax.Array] | None = None,
) -> EnvState:
    """A fresh episode-start state with zeroed bookkeeping."""
    obs = jnp.asarray(obs, jnp.float32)
    zero = jnp.zeros((), jnp.float32)
    return EnvState(
        physics=physics,
        task=task,
        obs=obs,
        reward=zero,
        terminated=jnp.zeros((), bool),
        truncated=jnp.zeros((), bool),
        final_obs=obs,
        first=jnp.ones((), bool),
        step_count=jnp.zeros((), jnp.int32),
        episode_return=zero,
        last_return=jnp.full((), jnp.nan, jnp.float32),
        last_length=jnp.zeros((), jnp.int32),
        metrics=dict(metrics or {}),
        key=key,
        blowup=jnp.zeros((), bool),
    )


ENV_AXIS = "envs"
"""Name of `VecEnv`'s vmap axis over envs."""


class VecEnv:
    """E copies of an `Env`, vmapped, with time limit and auto-reset.

    `reset(key) -> EnvState[E]` and `step(state[E], action[E, A]) -> EnvState[E]` are pure and
    jittable. After a step that ends an episode (terminated or truncated), `obs` is the reset
    observation of the next episode, `first` is True, and `final_obs` keeps the last observation.
    The next episode starts from `Env.reset_next` (task state carried over only where an env
    reproduces HumanoidBench's, `Task.carry`). After a step whose physics blew up, the env is
    reset the same way but `blowup` is True and no episode ended: `terminated`, `truncated` are
    False, `last_return`/`last_length` keep the previous finished episode's, and reward, metrics
    and `final_obs` hold nothing non-finite.

    The env axis of the vmap is named `ENV_AXIS`, so an env can call
    `jax.lax.axis_index(ENV_AXIS)` (the fault-injection wrapper in the tests does).
    """

    def __init__(self, env: Env, num_envs: int):
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.env = env
        self.num_envs = num_envs

    @property
    def observation_size(self) -> int:
        return self.env.observation_size

    @property
    def action_size(self) -> int:
        return self.env.action_size

    @property
    def episode_length(self) -> int:
        return self.env.episode_length

    @property
    def success_bar(self) -> float | None:
        return self.env.success_bar

    def reset(self, key: jax.Array) -> EnvState:
        keys = jax.random.split(key, self.num_envs)
        return jax.vmap(self.env.reset, axis_name=ENV_AXIS)(keys)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return jax.vmap(self._step_one, axis_name=ENV_AXIS)(state, action)

    def _step_one(self, state: EnvState, action: jax.Array) -> EnvState:
        nxt = self.env.step(state, action)
        blowup = ~(jnp.all(jnp.isfinite(nxt.obs)) & jnp.isfinite(nxt.reward)
                   & self.env.physics_finite(nxt.physics))  # fmt: skip
        step_count = state.step_count + 1
        terminated = jnp.asarray(nxt.terminated, bool) & ~blowup
        truncated = (step_count >= self.env.episode_length) & ~terminated & ~blowup
        done = terminated | truncated
        episode_return = state.episode_return + nxt.reward
        key_reset, key_next = jax.random.split(state.key)
        fresh = self.env.reset_next(key_reset, nxt)
        stepped = nxt.replace(
            terminated=terminated,
            truncated=truncated,
            final_obs=nxt.obs,
            first=jnp.zeros((), bool),
            step_count=step_count,
            episode_return=episode_return,
            last_return=jnp.where(done, episode_return, state.last_return),
            last_length=jnp.where(done, step_count, state.last_length),
            key=key_next,
            blowup=jnp.zeros((), bool),
        )
        reset = stepped.replace(
            physics=fresh.physics,
            task=fresh.task,
            obs=fresh.obs,
            first=jnp.ones((), bool),
            step_count=jnp.zeros((), jnp.int32),
            episode_return=jnp.zeros((), jnp.float32),
        )
        zero = jnp.zeros((), jnp.float32)
        blown = reset.replace(
            reward=zero,
            final_obs=fresh.obs,
            metrics={n: zero for n in nxt.metrics},
            last_return=state.last_return,
            last_length=state.last_length,
            blowup=jnp.ones((), bool),
        )
        out = jax.tree.map(lambda r, s: jnp.where(done, r, s), reset, stepped)
        return jax.tree.map(lambda b, o: jnp.where(blowup, b, o), blown, out)
