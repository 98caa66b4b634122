"""Per-run scalars: the plain numbers of an `AgentConfig` that a sweep varies inside one program.

A learner's state carries them (`state.hyper`: key -> [] float32), initialised from its config,
and its update reads them there rather than baking the config's value into the program. A run
trained alone therefore runs the same program as any run of a sweep, which writes its own
values over the ones `init` gave (`sirl_jax.sweep`). Every other config field is static: it
sets array shapes or what is traced, and a sweep refuses it.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

SWEEPABLE: dict[str, str] = {
    "sirl.beta": "the self-imitative term's weight (both learners; 0 is the plain learner)",
}
"""AgentConfig field path -> what it is: the fields a sweep may vary."""


def key(field: str) -> str:
    """The key of `field` in `state.hyper` (a checkpoint leaf name: no dots)."""
    return field.replace(".", "_")


def get(obj, field: str):
    """The value of a dotted field path of a (nested) dataclass."""
    return functools.reduce(getattr, field.split("."), obj)


def init_hyper(cfg) -> dict[str, jax.Array]:
    """{key: [] float32} of every sweepable field, from `cfg` (an `AgentConfig`)."""
    return {key(f): jnp.float32(get(cfg, f)) for f in SWEEPABLE}


def with_hyper(state, cfg):
    """`state` (a learner's) carrying `cfg`'s per-run values: a state made by one agent, updated
    by another agent's config (a test's shared init, say)."""
    return state.replace(hyper=init_hyper(cfg))
