"""Environments: the functional env contract, the task registry and the tasks."""

from sirl_jax.envs.base import Env, EnvState, VecEnv, init_state
from sirl_jax.envs.registry import TASKS, TaskSpec, make, register

__all__ = ["TASKS", "Env", "EnvState", "TaskSpec", "VecEnv", "init_state", "make", "register"]

# Register the built-in tasks (factories are lazy: no model is compiled at import).
import sirl_jax.envs.classic  # noqa: E402, F401
import sirl_jax.envs.tasks  # noqa: E402, F401
