"""Our HumanoidBench tasks as MuJoCo Playground environments, for any Playground or brax trainer.

    from mujoco_playground import wrapper
    from brax.training.agents.ppo import train as ppo
    from sirl_jax.envs import playground_env
    from sirl_jax.envs.playground_env import brax_compat

    brax_compat()                                      # brax 0.14.2 on JAX >= 0.10 (below)
    env = playground_env("h1hand-stand-v0")            # a mujoco_playground.MjxEnv
    make_policy, params, _ = ppo.train(environment=env, num_timesteps=..., episode_length=1000,
                                       wrap_env_fn=wrapper.wrap_for_brax_training)

The env steps our task (`sirl_jax.envs.load`, HumanoidBench's rewards, terminations, contacts
and observation) under Playground's conventions: `State.data` is the task's `mjx.Data`, `obs`
the [O] observation, `reward`, `done` (float: a termination, or non-finite physics, which
Playground's own envs also end an episode on), `metrics` the reward terms, and `info["task"]`
the task's own state (a goal, a stage). Time limits and resets belong to the wrappers
(`wrap_for_brax_training`: its episode length, and its reset to each env's cached first state,
or a full reset). With the cached first state only `data` and `obs` are put back; the task
state is put back too, because a step that starts from data at time 0 (an episode's first
step) takes the task state of the reset (`info["first_task"]`). HumanoidBench's state carried
across episodes (`Env.reset_next`) is not kept: under Playground every episode starts as
`reset` does, as Playground's own envs do. `mjx_model` may be replaced (brax's domain
randomization wrapper sets `_mjx_model`); the step runs on whichever model is set.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from sirl_jax.envs.humanoid import HumanoidEnv
from sirl_jax.envs.loading import load


def _playground():
    try:
        from ml_collections import config_dict
        from mujoco_playground._src import mjx_env
    except ImportError as err:
        raise ImportError("playground_env needs the optional extra: pip install "
                          f"'sirl_jax[playground]' (importing mujoco_playground failed: {err})"
                          ) from err  # fmt: skip
    return mjx_env, config_dict


def playground_env(name: str, **env_options) -> Any:
    """Task `name` (an id or alias of a HumanoidBench task: h1hand-*, h1-*) as a
    `mujoco_playground.MjxEnv`; `env_options` are `sirl_jax.envs.load`'s (hb_compat,
    contact_set, hand_floor, contact_budget)."""
    mjx_env, config_dict = _playground()
    spec, env = load(name, **env_options)
    if not isinstance(env, HumanoidEnv):
        raise ValueError(f"playground_env({name!r}): {spec.id} is not a HumanoidBench task; "
                         "allowed: the h1hand-* and h1-* tasks (python -m sirl_jax tasks)")

    class HumanoidBenchEnv(mjx_env.MjxEnv):
        """One sirl_jax HumanoidBench task under Playground's `MjxEnv` interface."""

        def __init__(self):
            timestep = float(env.mj_model.opt.timestep)
            super().__init__(config_dict.create(
                ctrl_dt=float(env.control_dt), sim_dt=timestep,
                episode_length=int(spec.episode_length), action_repeat=1))  # fmt: skip
            self.task_id, self.success_bar, self._env = spec.id, spec.success_bar, env
            self._mjx_model = env.mx

        def _ours(self) -> HumanoidEnv:
            return self._env if self._mjx_model is self._env.mx else self._env.with_model(
                self._mjx_model)  # fmt: skip

        def reset(self, rng: jax.Array):
            s = self._ours().reset(rng)
            return mjx_env.State(data=s.physics, obs=s.obs, reward=s.reward,
                                 done=jnp.zeros((), jnp.float32), metrics=s.metrics,
                                 info={"task": s.task, "first_task": s.task})  # fmt: skip

        def step(self, state, action: jax.Array):
            ours = self._ours()
            first = state.data.time == 0  # an episode's first step, after any kind of reset
            task = jax.tree.map(lambda a, b: jnp.where(first, a, b), state.info["first_task"],
                                state.info["task"])  # fmt: skip
            inner = _inner(state, task)
            out = ours.step(inner, action)
            bad = ~ours.physics_finite(out.physics) | ~jnp.all(jnp.isfinite(out.obs))
            done = (out.terminated | bad).astype(jnp.float32)
            info = {**state.info, "task": out.task}
            return state.replace(data=out.physics, obs=jnp.where(bad, inner.obs, out.obs),
                                 reward=jnp.where(bad, 0.0, out.reward), done=done,
                                 metrics={**state.metrics, **out.metrics},  # wrappers' too
                                 info=info)  # fmt: skip

        @property
        def xml_path(self) -> str:
            return f"sirl_jax:{spec.id}"  # built in code (sirl_jax/envs/tasks), not from a file

        @property
        def action_size(self) -> int:
            return int(env.action_size)

        @property
        def mj_model(self):
            return env.mj_model

        @property
        def mjx_model(self):
            return self._mjx_model

    return HumanoidBenchEnv()


def brax_compat() -> bool:
    """brax 0.14.2's trainers (the newest brax on PyPI) call `jax.device_put_replicated`,
    which JAX 0.10 removed. This puts back the drop-in JAX's migration guide gives (the value
    stacked once per device, sharded over them), so they run unchanged; a JAX that still has
    it is left alone. Returns whether it was put back."""
    import numpy as np

    if "device_put_replicated" in vars(jax) or not _removed(jax, "device_put_replicated"):
        return False

    def device_put_replicated(x, devices):
        mesh = jax.sharding.Mesh(np.asarray(devices), ("devices",))
        sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("devices"))
        return jax.tree.map(lambda a: jax.device_put(jnp.stack([a] * len(devices)), sharding), x)

    jax.device_put_replicated = device_put_replicated
    return True


def _removed(module, name: str) -> bool:
    try:
        getattr(module, name)
    except AttributeError:
        return True
    return False


def _inner(state, task):
    """Our `EnvState` for `Env.step` from a Playground state (only what `step` reads)."""
    from sirl_jax.envs.base import init_state

    return init_state(state.data, state.obs, jnp.zeros((2,), jnp.uint32), task=task,
                      metrics=state.metrics)  # fmt: skip
