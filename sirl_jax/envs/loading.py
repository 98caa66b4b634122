"""`load(name) -> (TaskSpec, Env)`: the one place a task name becomes an environment.

Names: a registry id (`h1hand-walk-v0`, `pendulum`), an alias (`walk`), or a prefixed name
for an optional family: `dmc:<Name>` / `playground:<Name>` (MuJoCo Playground, optional
extra). The env is the source of truth for its episode length and success bar: the returned
spec carries the env's values, so a factory override (`episode_length=...`) cannot leave the
two disagreeing.
"""

from __future__ import annotations

import dataclasses

from sirl_jax.envs.base import Env
from sirl_jax.envs.playground_adapter import PREFIXES, register_playground_task
from sirl_jax.envs.registry import TASKS, TaskSpec

__all__ = ["PREFIXES", "load", "spec"]


def spec(name: str) -> TaskSpec:
    """The registered spec of `name` without building its env (registers Playground tasks).

    Raises:
      KeyError: an unknown task or prefix (the message lists what is allowed).
      ImportError: a Playground task without the `playground` extra installed.
    """
    if name.startswith(PREFIXES):
        return register_playground_task(name)
    prefix, colon, _ = name.partition(":")
    if colon:
        raise KeyError(
            f"unknown task prefix {prefix + ':'!r} in {name!r}; allowed prefixes: "
            f"{', '.join(PREFIXES)}, or a registered task id (python -m sirl_jax tasks)"
        )
    return TASKS.resolve(name)


def load(name: str, **kwargs) -> tuple[TaskSpec, Env]:
    """(spec, env) of a task; `kwargs` go to the task's factory (e.g. `episode_length`)."""
    registered = spec(name)
    env = registered.factory(**kwargs)
    return (
        dataclasses.replace(
            registered, episode_length=env.episode_length, success_bar=env.success_bar
        ),
        env,
    )
