"""Environments: the functional env contract, the task registry and the tasks."""

from sirl_jax.envs.base import Env, EnvState, VecEnv, init_state
from sirl_jax.envs.registry import TASKS, TaskSpec, make, register

__all__ = ["TASKS", "Env", "EnvState", "TaskSpec", "VecEnv", "init_state", "make", "register"]
