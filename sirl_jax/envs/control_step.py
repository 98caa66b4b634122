"""The control step: a `ctrl` held for HumanoidBench's 10 physics substeps (`lax.scan` of
`mjx.step`), and the same step reporting whether an MJX contact budget was full."""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
from mujoco import mjx

from sirl_jax.envs import physics as _physics
from sirl_jax.envs.h1 import N_SUBSTEPS


def make_control_step(
    n_substeps: int = N_SUBSTEPS,
) -> Callable[[mjx.Model, mjx.Data, jax.Array], mjx.Data]:
    """Returns `step(mx, d, ctrl) -> d`: hold `ctrl` [nu] for `n_substeps` `mjx.step` calls
    (a `lax.scan`), as HumanoidBench's `do_simulation`."""

    def step(mx: mjx.Model, d: mjx.Data, ctrl: jax.Array) -> mjx.Data:
        d = d.replace(ctrl=ctrl)
        d, _ = jax.lax.scan(lambda d, _: (mjx.step(mx, d), None), d, None, length=n_substeps)
        return d

    return step


def make_budget_control_step(
    budget: int, n_substeps: int = N_SUBSTEPS
) -> Callable[[mjx.Model, mjx.Data, jax.Array], tuple[mjx.Data, jax.Array]]:
    """`make_control_step` for a model with an MJX contact budget (`max_contact_points`):
    `step(mx, d, ctrl) -> (d, full)`, full [] float32 1 when the budget was full (every kept
    contact active, `physics.budget_full`) after any of the substeps' collisions."""

    def substep(mx: mjx.Model, carry, _):
        d, full = carry
        d = mjx.step(mx, d)
        return (d, full | _physics.budget_full(d, budget)), None

    def step(mx: mjx.Model, d: mjx.Data, ctrl: jax.Array) -> tuple[mjx.Data, jax.Array]:
        carry = (d.replace(ctrl=ctrl), jnp.zeros((), bool))
        (d, full), _ = jax.lax.scan(functools.partial(substep, mx), carry, None,
                                    length=n_substeps)  # fmt: skip
        return d, full.astype(jnp.float32)

    return step
