"""MuJoCo C states of the HumanoidBench tasks for the hb_compat tests: each task's env built
once per process, and the fields a task's `evaluate` reads, from MuJoCo C data."""

from __future__ import annotations

import types

import jax.numpy as jnp
import mujoco
import numpy as np

from sirl_jax.envs import make

_BUILT: dict[str, object] = {}


def task_env(name: str):
    """The task's env (default mode), built once per module; `.task.with_hb_compat(mode)`
    gives either mode's task on the same model (both modes compile the same model)."""
    if name not in _BUILT:
        _BUILT[name] = make(name)
    return _BUILT[name]


def task_of(name: str, mode: str):
    return task_env(name).task.with_hb_compat(mode)


def forward_c(env, qpos=None) -> mujoco.MjData:
    """MuJoCo C data at keyframe 0 (or `qpos`) after `mj_forward`."""
    m = env.mj_model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    if qpos is not None:
        d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    return d


def task_data(d: mujoco.MjData, **extra) -> types.SimpleNamespace:
    """The fields a task's `evaluate` reads, from MuJoCo C data (no active contact unless
    `contact` is given)."""
    no_contact = types.SimpleNamespace(dist=np.ones(1), geom=np.zeros((1, 2), int))
    fields = dict(qpos=d.qpos, xpos=d.xpos, xmat=d.xmat.reshape(-1, 3, 3), site_xpos=d.site_xpos,
                  geom_xpos=d.geom_xpos, geom_xmat=d.geom_xmat, actuator_force=d.actuator_force,
                  contact=no_contact)  # fmt: skip
    fields.update(extra)
    return types.SimpleNamespace(**{k: jnp.asarray(v) if isinstance(v, np.ndarray) else v
                                    for k, v in fields.items()})  # fmt: skip
