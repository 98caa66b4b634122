"""Train on any MuJoCo Playground `MjxEnv` (`--task dmc:CartpoleSwingup`).

The PyPI package `playground` (module `mujoco_playground`) is an optional extra
(`pip install 'sirl_jax[playground]'`); it is imported only when such a task is requested.

Names: `dmc:<Name>` for the dm_control suite ports, `playground:<Name>` for any env in the
Playground registry (locomotion, manipulation, dm_control). A dict observation uses its
`state` entry. Playground's `done` (a fall, or NaN physics in the dm_control ports) becomes
`terminated`; the time limit is `episode_length / action_repeat` from the env's config and is
enforced by `VecEnv`, not by Playground's wrappers. Physics runs with `impl="jax"` unless
`impl` (or `physics`, which also sizes Warp's buffers from the env's contact profile, as
`sirl_jax/envs/physics.py` does for our tasks) says otherwise; Playground's default, warp, is
slow or unavailable on CPU.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp

from sirl_jax.envs.base import Env, EnvState, init_state
from sirl_jax.envs.physics import OVERFLOW_METRIC, Physics, Simulator
from sirl_jax.envs.registry import TASKS, TaskSpec, register

PREFIXES = ("dmc:", "playground:")
"""Task-name prefixes this adapter handles."""


def _import_playground():
    try:
        from mujoco_playground import registry
    except ImportError as err:
        raise ImportError(
            "MuJoCo Playground tasks need the optional extra: pip install 'sirl_jax[playground]' "
            f"(the `playground` package); importing mujoco_playground failed with: {err}"
        ) from err
    return registry


def _split_name(name: str) -> tuple[str, str]:
    for prefix in PREFIXES:
        if name.startswith(prefix):
            return prefix[:-1], name[len(prefix) :]
    raise ValueError(f"task {name!r} is not a Playground task; names start with {PREFIXES}")


class PlaygroundEnv(Env):
    """Adapts one Playground `MjxEnv` to the `Env` contract.

    `physics` holds Playground's whole `State` (data, info, metrics), so its own per-env
    bookkeeping (command targets, RNG) carries through unchanged.
    """

    def __init__(
        self,
        name: str,
        impl: str | None = "jax",
        action_repeat: int = 1,
        physics: Physics | None = None,
        instance: Any = None,
    ):
        """instance: an `MjxEnv` to adapt as it is (e.g. `sirl_jax.envs.playground_env`'s),
        instead of loading `name` from Playground's registry (MJX-JAX only)."""
        if action_repeat < 1:
            raise ValueError(f"action_repeat={action_repeat!r} is invalid; allowed: >= 1")
        if instance is not None:
            self.env, self.sim, self.name, self.action_repeat = instance, None, name, action_repeat
            self._describe()
            return
        suite, env_name = _split_name(name)
        registry = _import_playground()
        valid = registry.dm_control_suite.ALL_ENVS if suite == "dmc" else registry.ALL_ENVS
        if env_name not in valid:
            raise ValueError(f"unknown {suite} env {env_name!r}; valid: {', '.join(valid)}")
        if physics is None and impl == "warp":
            physics = Physics("warp")
        impl = physics.impl if physics is not None else impl
        overrides = {"impl": impl} if impl is not None else None
        self.env = registry.load(env_name, config_overrides=overrides)
        self.sim = None
        if physics is not None and physics.impl == "warp":
            self.sim = Simulator(self.env.mj_model, physics)
            missing = {"naconmax", "njmax"} - set(self.env._config.keys())
            if missing:
                raise ValueError(f"{name} has no {sorted(missing)} in its config, so Warp's "
                                 "buffers cannot be sized; use impl='jax'")  # fmt: skip
            buffers = self.sim.buffers
            overrides.update(naconmax=buffers.naconmax, njmax=buffers.njmax)
            self.env = registry.load(env_name, config_overrides=overrides)
        self.name = name
        self.action_repeat = action_repeat
        self._describe()

    def _describe(self) -> None:
        self._episode_length = int(self.env._config.episode_length) // self.action_repeat
        probe = jax.eval_shape(self.env.reset, jax.random.PRNGKey(0))
        self._obs_size = int(self._flat_obs(probe.obs).shape[-1])
        self._metric_names = tuple(sorted(probe.metrics))
        self._extra = (OVERFLOW_METRIC,) if self.sim is not None else ()

    @property
    def physics_impl(self) -> str:
        return "jax" if self.sim is None else self.sim.impl

    def with_physics(self, physics: Physics) -> PlaygroundEnv:
        """The same env rebuilt to simulate with `physics` (impl, worlds, Warp buffer margin)."""
        return PlaygroundEnv(self.name, action_repeat=self.action_repeat, physics=physics)

    def _attach(self, pg_state: Any) -> Any:
        return pg_state if self.sim is None else pg_state.replace(
            data=self.sim.attach_pool(pg_state.data))  # fmt: skip

    def _detach(self, pg_state: Any) -> Any:
        return pg_state if self.sim is None else pg_state.replace(
            data=self.sim.detach_pool(pg_state.data))  # fmt: skip

    @staticmethod
    def _flat_obs(obs: Any) -> jax.Array:
        if isinstance(obs, Mapping):
            if "state" not in obs:
                raise ValueError(f"dict observation without a 'state' entry: keys {list(obs)}")
            obs = obs["state"]
        return obs

    @property
    def mj_model(self):
        return self.env.mj_model

    @property
    def control_dt(self) -> float:
        return float(self.env.dt) * self.action_repeat

    def mjx_data(self, physics: Any) -> Any:
        return physics.data

    @property
    def observation_size(self) -> int:
        return self._obs_size

    @property
    def action_size(self) -> int:
        return int(self.env.action_size)

    @property
    def episode_length(self) -> int:
        return self._episode_length

    def metric_names(self) -> tuple[str, ...]:
        return self._metric_names + self._extra

    def _metrics(self, pg_state: Any, overflow: jax.Array | None = None) -> dict[str, jax.Array]:
        metrics = {k: jnp.asarray(pg_state.metrics[k], jnp.float32) for k in self._metric_names}
        if self._extra:
            metrics[OVERFLOW_METRIC] = jnp.zeros((), jnp.float32) if overflow is None else overflow
        return metrics

    def reset(self, key: jax.Array) -> EnvState:
        key_env, key_next = jax.random.split(key)
        pg_state = self.env.reset(key_env)
        obs = self._flat_obs(pg_state.obs)
        return init_state(self._detach(pg_state), obs, key_next, metrics=self._metrics(pg_state))

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        def repeat(carry, _):
            pg_state, total = carry
            nxt = self.env.step(pg_state, action)
            # Once done, later repeats add no reward (the episode has ended).
            alive = 1.0 - jnp.asarray(pg_state.done, jnp.float32)
            return (nxt, total + alive * nxt.reward), None

        (pg_state, reward), _ = jax.lax.scan(
            repeat,
            (self._attach(state.physics), jnp.zeros((), jnp.float32)),
            None,
            length=self.action_repeat,
        )
        overflow = None
        if self.sim is not None:
            data, overflow = self.sim.pop_overflow(pg_state.data)
            pg_state = pg_state.replace(data=data)
        return state.replace(
            physics=self._detach(pg_state),
            obs=jnp.asarray(self._flat_obs(pg_state.obs), jnp.float32),
            reward=jnp.asarray(reward, jnp.float32),
            terminated=jnp.asarray(pg_state.done, bool),
            metrics=self._metrics(pg_state, overflow),
        )


def register_playground_task(name: str, action_repeat: int = 1) -> TaskSpec:
    """Registers `name` (e.g. `dmc:CartpoleSwingup`) if needed and returns its spec.

    Building the spec loads the env once to read its episode length.
    """
    if name in TASKS:
        return TASKS[name]
    env = PlaygroundEnv(name, action_repeat=action_repeat)
    return register(
        TaskSpec(
            id=name,
            factory=lambda **kw: PlaygroundEnv(name, **{"action_repeat": action_repeat, **kw}),
            episode_length=env.episode_length,
            description=f"MuJoCo Playground env {name}",
        )
    )
