"""Environments: the functional env contract, the task registry, task loading and the tasks."""

from sirl_jax.envs.base import Env, EnvState, VecEnv, init_state
from sirl_jax.envs.loading import PREFIXES, load, spec
from sirl_jax.envs.registry import TASKS, TaskSpec, make, register

__all__ = [
    "PREFIXES", "TASKS", "Env", "EnvState", "TaskSpec", "VecEnv", "init_state", "load", "make",
    "playground_env", "register", "spec",
]  # fmt: skip


def playground_env(name: str, **env_options):
    """Task `name` as a `mujoco_playground.MjxEnv` (`sirl_jax.envs.playground_env`)."""
    from sirl_jax.envs.playground_env import playground_env as make_env

    return make_env(name, **env_options)

# Register the built-in tasks (factories are lazy: no model is compiled at import).
import sirl_jax.envs.classic  # noqa: E402, F401
import sirl_jax.envs.tasks  # noqa: E402, F401
