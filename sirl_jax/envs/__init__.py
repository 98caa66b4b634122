"""Environments: the functional env contract, the task registry, task loading and the tasks."""

from sirl_jax.envs.base import Env, EnvState, VecEnv, init_state
from sirl_jax.envs.loading import PREFIXES, load, spec
from sirl_jax.envs.registry import TASKS, TaskSpec, make, register

__all__ = [
    "PREFIXES", "TASKS", "Env", "EnvState", "TaskSpec", "VecEnv", "init_state", "load", "make",
    "register", "spec",
]  # fmt: skip

# Register the built-in tasks (factories are lazy: no model is compiled at import).
import sirl_jax.envs.classic  # noqa: E402, F401
import sirl_jax.envs.tasks  # noqa: E402, F401
