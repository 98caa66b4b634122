"""Per-run scalars: the plain numbers of an `AgentConfig` that a sweep varies inside one program.

A learner's state carries them (`state.hyper`: key -> [] float32), initialised from its config
by `init_hyper`, and its update and acting read them there rather than baking the config's
value into the program. A run trained alone therefore runs the same program as any run of a
sweep, which writes each run's own values over the ones `init` gave (`sirl_jax.sweep`).
Every other config field is static: it sets array shapes or what is traced, and a sweep
refuses it. tests/test_hyper.py checks, field by field, that changing a sweepable field leaves
the learner's traced program unchanged and changes only `state.hyper`.

The learning rates and weight decay enter the optimisers this way too: the optax chain is
built inside the update from the traced values (`optax.adam(lr)` with lr a [] array, as
`optax.inject_hyperparams` would), and its state, which does not depend on them, is the same.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp

BOTH = ("tdmpc2", "fasttd3")

SWEEPABLE: dict[str, tuple[tuple[str, ...], str]] = {
    "sirl.beta": (BOTH, "the self-imitative term's weight (0 is the plain learner)"),
    "lr": (("tdmpc2",), "Adam learning rate of the world model and the policy"),
    "enc_lr_scale": (("tdmpc2",), "the encoder's learning rate is lr x this"),
    "tau": (("tdmpc2",), "Polyak rate of the target Qs and rate of the running Q scale"),
    "entropy_coef": (("tdmpc2",), "the policy's entropy bonus"),
    "consistency_coef": (("tdmpc2",), "weight of the latent consistency loss"),
    "reward_coef": (("tdmpc2",), "weight of the reward loss"),
    "value_coef": (("tdmpc2",), "weight of the value loss"),
    "fasttd3.actor_lr": (("fasttd3",), "AdamW learning rate of the actor"),
    "fasttd3.critic_lr": (("fasttd3",), "AdamW learning rate of the critics"),
    "fasttd3.weight_decay": (("fasttd3",), "AdamW weight decay (both optimisers)"),
    "fasttd3.tau": (("fasttd3",), "Polyak rate of the target critic"),
    "fasttd3.policy_noise": (("fasttd3",), "std of the target policy smoothing noise"),
    "fasttd3.noise_clip": (("fasttd3",), "clip of the target policy smoothing noise"),
    "fasttd3.std_min": (("fasttd3",), "lowest per-env exploration noise std"),
    "fasttd3.std_max": (("fasttd3",), "highest per-env exploration noise std"),
}
"""AgentConfig field path -> (the learners that read it, what it is): the fields a sweep may
vary. A field of the other learner is static for this one (it is not read at all)."""

DERIVED: dict[str, tuple[tuple[str, ...], Callable]] = {
    # the encoder's rate as TD-MPC2 computes it, once in float64 (a traced product of the two
    # float32 values can round differently)
    "enc_lr": (("tdmpc2",), lambda cfg: cfg.lr * cfg.enc_lr_scale),
}
"""Values computed from sweepable fields, carried beside them: key -> (learners, cfg -> value)."""


def key(field: str) -> str:
    """The key of `field` in `state.hyper` (a checkpoint leaf name: no dots)."""
    return field.replace(".", "_")


def get(obj, field: str):
    """The value of a dotted field path of a (nested) dataclass."""
    return functools.reduce(getattr, field.split("."), obj)


def fields(kind: str) -> list[str]:
    """The sweepable fields that learner `kind` reads."""
    return [f for f, (kinds, _) in SWEEPABLE.items() if kind in kinds]


def init_hyper(cfg) -> dict[str, jax.Array]:
    """{key: [] float32}: every sweepable field `cfg.kind`'s learner reads, and the values
    derived from them, from `cfg` (an `AgentConfig`)."""
    out = {key(f): jnp.float32(get(cfg, f)) for f in fields(cfg.kind)}
    out.update({k: jnp.float32(fn(cfg)) for k, (kinds, fn) in DERIVED.items()
                if cfg.kind in kinds})  # fmt: skip
    return out


class Hyper:
    """`state.hyper` read by field path: `Hyper(state.hyper)["fasttd3.actor_lr"]`."""

    def __init__(self, hyper: dict):
        self.hyper = hyper

    def __getitem__(self, field: str) -> jax.Array:
        return self.hyper[key(field)]

    @classmethod
    def of(cls, cfg, h: Hyper | None = None) -> Hyper:
        """`h`, or when None the values of `cfg` (a caller outside a learner's update)."""
        return cls(init_hyper(cfg)) if h is None else h


def with_hyper(state, cfg):
    """`state` (a learner's) carrying `cfg`'s per-run values: a state made by one agent, updated
    by another agent's config (a test's shared init, say)."""
    return state.replace(hyper=init_hyper(cfg))
