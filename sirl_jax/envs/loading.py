"""`load(name) -> (TaskSpec, Env)`: the one place a task name becomes an environment.

Names: a registry id (`h1hand-walk-v0`, `pendulum`), an alias (`walk`), or a prefixed name
for an optional family: `dmc:<Name>` / `playground:<Name>` (MuJoCo Playground, optional
extra). The env is the source of truth for its episode length and success bar: the returned
spec carries the env's values, so a factory override (`episode_length=...`) cannot leave the
two disagreeing. `hb_compat` says how HumanoidBench's quirks are treated and `contact_set`
what the manipulation scenes' colliders touch (`hb_compat.py`).
`physics` picks the MJX backend (`sirl_jax/envs/physics.py`): factories build
MJX-JAX envs, and `with_physics` rebuilds one for another impl.
"""

from __future__ import annotations

import dataclasses

from sirl_jax.envs.base import Env
from sirl_jax.envs.physics import Physics, check_impl
from sirl_jax.envs.playground_adapter import PREFIXES, register_playground_task
from sirl_jax.envs.registry import TASKS, TaskSpec
from sirl_jax.hb_compat import (
    EXACT,
    HAND_FLOOR,
    HB,
    TASK_BUDGET,
    check_contact_budget,
    check_contact_set,
    check_hand_floor,
    check_hb_compat,
)

__all__ = ["PREFIXES", "load", "spec", "with_physics"]


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


def with_physics(env: Env, physics: Physics) -> Env:
    """`env` simulating with `physics`; an MJX-JAX env is returned as is for impl="jax".

    Raises:
      ImportError / RuntimeError: impl="warp" where warp-lang is missing / Warp cannot run.
      ValueError: the env cannot switch its physics (`Env.with_physics`'s default).
    """
    check_impl(physics.impl)
    if physics.impl == "jax" and env.physics_impl == "jax":
        return env
    return env.with_physics(physics)


def load(
    name: str,
    physics: Physics | None = None,
    hb_compat: str = EXACT,
    contact_set: str = HB,
    hand_floor: str = HAND_FLOOR[0],
    contact_budget: int = TASK_BUDGET,
    **kwargs,
) -> tuple[TaskSpec, Env]:
    """(spec, env) of a task; `kwargs` go to the task's factory (e.g. `episode_length`).

    physics: the MJX backend (None: MJX-JAX); impl="warp" is checked before anything is built.
    hb_compat: HumanoidBench's quirks, "exact" (reproduced) or "fixed" (corrected)
      (`sirl_jax/hb_compat.py`); checked for every task, used by HumanoidBench's tasks.
    contact_set: "hb" (HumanoidBench's contacts) or "reduced" (the cheaper cut set of the
      manipulation scenes); checked for every task, used by the manipulation tasks.
    hand_floor: which hand colliders touch the floor, "all" (HumanoidBench's), "palms" or
      "none"; used by the HumanoidBench tasks on a robot with hands.
    contact_budget: MJX-JAX's contact budget (`max_contact_points`): -1 the task's own, 0
      none, k >= 1 k; used by HumanoidBench's tasks.
    """
    check_hb_compat(hb_compat)
    check_contact_set(contact_set)
    check_hand_floor(hand_floor)
    check_contact_budget(contact_budget)
    if physics is not None:
        check_impl(physics.impl)
    registered = spec(name)
    if registered.takes_hb_compat:
        kwargs["hb_compat"] = hb_compat
        kwargs["contact_set"] = contact_set
        kwargs["hand_floor"] = hand_floor
        kwargs["contact_budget"] = contact_budget
    env = registered.factory(**kwargs)
    if physics is not None:
        env = with_physics(env, physics)
    return (
        dataclasses.replace(
            registered, episode_length=env.episode_length, success_bar=env.success_bar
        ),
        env,
    )
