"""The physics backend of the MJX envs: `impl` "jax" (MJX in XLA) or "warp" (MJX-Warp).

`Physics` is the choice (impl, worlds, buffer margin); `Simulator` applies it to one compiled
`MjModel`: the `mjx.Model`, the episode-start `mjx.Data`, and, for Warp, the shared contact pool.

MJX-Warp differs from MJX-JAX in two ways that the env contract sees:

- Buffers are sized up front. Warp keeps one pool of `naconmax` contacts for all the worlds
  stepped together (every env of every vmapped seed) and `njmax` constraint rows per world;
  more is dropped, and the world's `overflow` bitmask says so. `warp_buffers` sizes both from
  the task's contact profile (the slots MJX-JAX allocates: one per contact a candidate geom pair
  can make, so the worst case, fall included) times a margin; `Simulator.pop_overflow` reads
  the bitmask after each control step, so an env reports every step that dropped anything.
- The contact pool is not per world, so `VecEnv`'s per-env `where` (auto-reset) cannot carry it.
  An env keeps its state without the pool (`detach_pool`: empty placeholders) and puts the
  pool back before stepping (`attach_pool`); collision recomputes it every step anyway.

MJX-JAX can be given a contact budget (the model's `max_contact_points` numeric: the solver
sees only the most penetrating contacts). When every contact of the budget is active at a
substep, an active one may have been left out; `Simulator.contact_budget` names the budget and
the env reports such steps under the same metric as Warp's overflows.

Warp has no autodiff; nothing here differentiates the physics. On the CPU, Warp runs through
its CPU device (slower than MJX-JAX there, docs/training.md).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import importlib
import math
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from sirl_jax.agent.config import check as _check

IMPLS = ("jax", "warp")
"""MJX backends: "jax" (XLA, any device) and "warp" (MJX-Warp: CUDA GPU or CPU, warp-lang)."""

# MuJoCo Warp's OverflowType bits (mujoco_warp/_src/types.py) of a buffer that was too small.
# ITERATIONS (1 << 9) and LS_ITERATIONS (1 << 10) are solver limits, not dropped data.
OVERFLOW_BITS = {
    "nefc > njmax": 1 << 0,
    "njmax_nnz": 1 << 1,
    "broadphase pairs > naconmax": 1 << 2,
    "contacts > naconmax": 1 << 3,
    "ccd": 1 << 4,
    "height field": 1 << 5,
    "contact sensor match": 1 << 6,
    "nvmax": 1 << 7,
    "epa horizon": 1 << 8,
}
BUFFER_OVERFLOW = functools.reduce(lambda a, b: a | b, OVERFLOW_BITS.values())
_CONTACT_ROWS = tuple(
    int(c) for c in (mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS,
                     mujoco.mjtConstraint.mjCNSTR_CONTACT_PYRAMIDAL,
                     mujoco.mjtConstraint.mjCNSTR_CONTACT_ELLIPTIC)
)  # fmt: skip
OVERFLOW_METRIC = "physics_overflow"
"""Per-step metric: 1 when a Warp buffer of the env's world overflowed during the step, or, with
MJX-JAX and a contact budget, when the budget was full at one of its substeps (an active contact
may have been left out)."""


@dataclasses.dataclass(frozen=True)
class Physics:
    """How an MJX env simulates.

    Attributes:
      impl: "jax" or "warp".
      num_worlds: Warp only: worlds stepped together in one program (seeds x envs, S * E),
        which share one contact pool of `num_worlds` times the per-world bound.
      margin: Warp only: buffers hold `margin` times the task's worst case per world.
    """

    impl: str = "jax"
    num_worlds: int = 1
    margin: float = 1.5

    def __post_init__(self) -> None:
        _check(self.impl in IMPLS, "impl", self.impl, " or ".join(map(repr, IMPLS)))
        _check(self.num_worlds >= 1, "num_worlds", self.num_worlds, "an int >= 1")
        _check(math.isfinite(self.margin) and self.margin > 0, "margin", self.margin, "a float > 0")


def _import_warp():
    """The `warp` module, quiet, with MJX's Warp bindings importable (ImportError if not)."""
    warp = importlib.import_module("warp")
    importlib.import_module("mujoco.mjx.third_party.mujoco_warp")
    if hasattr(warp, "LOG_WARNING"):  # warp-lang >= 1.19: log levels replace `quiet`
        warp.config.log_level = max(warp.config.log_level, warp.LOG_WARNING)
    else:
        warp.config.quiet = True
    return warp


def warp_unavailable() -> str | None:
    """Why impl="warp" cannot run here, in one line; None when it can."""
    try:
        _import_warp()
    except ImportError as e:
        why = (str(e).splitlines() or [type(e).__name__])[0]
        return f"warp-lang is not installed ({why}); pip install 'sirl_jax[warp]' or use impl='jax'"
    backend = jax.default_backend()
    if backend not in ("cpu", "gpu", "cuda"):
        return f"Warp runs on a CUDA GPU or the CPU, and the JAX default backend is {backend!r}"
    if backend != "cpu" and not any(d.platform in ("gpu", "cuda") for d in jax.devices()):
        return f"Warp needs a CUDA device; the JAX devices are {jax.devices()}"
    return None


def check_impl(impl: str) -> None:
    """Raises a one-line error when `impl` is unknown or cannot run on this machine.

    Raises:
      ValueError: an unknown impl.
      ImportError: impl="warp" without warp-lang (or MJX's Warp bindings) installed.
      RuntimeError: impl="warp" on a device Warp cannot use.
    """
    Physics(impl=impl)
    if impl != "warp":
        return
    reason = warp_unavailable()
    if reason is None:
        return
    error = ImportError if reason.startswith("warp-lang") else RuntimeError
    raise error(f"impl='warp' cannot be used: {reason}")


def contact_profile(mj_model: mujoco.MjModel) -> tuple[int, int]:
    """(contacts, constraint rows) one world of `mj_model` can reach at most.

    The slots MJX-JAX allocates: a contact slot for each contact every candidate geom pair can
    make (contype/conaffinity and `<pair>`s, without the `max_geom_pairs` pruning and the
    `max_contact_points` budget of the JAX path, which Warp does not apply) and a constraint
    row for each contact row, joint and tendon limit, friction loss and equality.
    """
    model = copy.copy(mj_model)
    for name in ("max_geom_pairs", "max_contact_points"):
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, name)
        if i >= 0:
            model.numeric_data[model.numeric_adr[i]] = -1.0
    data = mjx.make_data(model, impl="jax")
    return int(data._impl.contact.dist.shape[0]), int(data._impl.efc_J.shape[0])


@dataclasses.dataclass(frozen=True)
class WarpBuffers:
    """Warp's buffer sizes. nconmax, njmax: per world; naconmax: the pool of all worlds."""

    nconmax: int
    njmax: int
    naconmax: int


def warp_buffers(mj_model: mujoco.MjModel, physics: Physics) -> WarpBuffers:
    """Buffers for `physics.num_worlds` worlds: `margin` x `contact_profile`, at least 1."""
    contacts, rows = contact_profile(mj_model)
    nconmax = max(1, math.ceil(physics.margin * contacts))
    njmax = max(1, math.ceil(physics.margin * rows))
    return WarpBuffers(nconmax, njmax, nconmax * physics.num_worlds)


def _pool_arrays(data: mjx.Data) -> dict[str, jax.Array]:
    """The arrays of Warp data shared by all worlds (not batched per world), by field name."""
    from mujoco.mjx.warp import types as warp_types

    impl = data._impl
    names = warp_types.DATA_NON_VMAP & {f.name for f in dataclasses.fields(impl)}
    return {n: getattr(impl, n) for n in sorted(names) if hasattr(getattr(impl, n), "shape")}


def overflow_names(bits: int) -> list[str]:
    """The buffer overflows set in a Warp `overflow` bitmask."""
    return [name for name, bit in OVERFLOW_BITS.items() if int(bits) & bit]


class Simulator:
    """One compiled model under one `Physics`: the `mjx.Model` and the episode-start data.

    Attributes:
      physics: the choice.
      mx: the `mjx.Model` (impl as chosen).
      buffers: Warp's buffer sizes (None for impl="jax").
      contact_budget: MJX-JAX's `max_contact_points` (0: none; always 0 for Warp).
    """

    def __init__(self, mj_model: mujoco.MjModel, physics: Physics | None = None):
        self.physics = physics or Physics()
        self.mj_model = mj_model
        if self.physics.impl == "jax":
            self.mx = mjx.put_model(mj_model, impl="jax")
            self.buffers, self._pool, self._data0 = None, None, None
            self.contact_budget = contact_budget(mj_model)
            return
        self.contact_budget = 0
        check_impl("warp")
        self.buffers = warp_buffers(mj_model, self.physics)
        mx = mjx.put_model(mj_model, impl="warp")
        # Solver iteration limits (1 Newton iteration here) are set on purpose: keep Warp's
        # per-step printout to the buffer overflows, which `pop_overflow` reports anyway.
        self.mx = mx.tree_replace({"opt._impl.warn_overflow": BUFFER_OVERFLOW})
        full = mjx.make_data(
            mj_model, impl="warp", naconmax=self.buffers.naconmax, njmax=self.buffers.njmax
        )
        self._pool = _pool_arrays(full)
        self._data0 = self.detach_pool(full)

    @property
    def impl(self) -> str:
        return self.physics.impl

    def make_data(self, mx: mjx.Model | None = None) -> mjx.Data:
        """A fresh `mjx.Data` (qpos0, zero velocities), without Warp's contact pool."""
        if self._data0 is None:
            return mjx.make_data(self.mx if mx is None else mx, impl="jax")
        return self._data0

    def attach_pool(self, data: mjx.Data) -> mjx.Data:
        """`data` ready for `mjx.step`: Warp's shared contact pool put back (jax: as is)."""
        if self._pool is None:
            return data
        return data.replace(_impl=data._impl.replace(**self._pool))

    def detach_pool(self, data: mjx.Data) -> mjx.Data:
        """`data` without Warp's shared contact pool (empty placeholders; jax: as is)."""
        if self._pool is None:
            return data
        empty = {n: jnp.zeros((0, *v.shape[1:]), v.dtype) for n, v in self._pool.items()}
        return data.replace(_impl=data._impl.replace(**empty))

    def pop_overflow(self, data: mjx.Data) -> tuple[mjx.Data, jax.Array]:
        """(data with its overflow bits cleared, [] float32 1 if a buffer overflowed since
        the last call); impl="jax" never drops contacts: (data, 0)."""
        if self._pool is None:
            return data, jnp.zeros((), jnp.float32)
        bits = data._impl.overflow
        hit = (bits & BUFFER_OVERFLOW) != 0
        cleared = data._impl.replace(overflow=jnp.zeros_like(bits))
        return data.replace(_impl=cleared), hit.astype(jnp.float32)


def contact_budget(mj_model: mujoco.MjModel) -> int:
    """The model's `max_contact_points` numeric (MJX-JAX's contact budget), 0 when unset."""
    i = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_NUMERIC, "max_contact_points")
    if i < 0:
        return 0
    return max(0, int(mj_model.numeric_data[mj_model.numeric_adr[i]]))


def budget_full(data: mjx.Data, budget: int) -> jax.Array:
    """[] bool: MJX-JAX kept `budget` contacts and every one of them is active (dist < 0), so an
    active contact may have been left out of the solver."""
    dist, _ = contact_arrays(data)
    return jnp.sum(dist < 0) >= budget


def contact_arrays(data: mjx.Data) -> tuple[jax.Array, jax.Array]:
    """(dist [C], geom [C, 2]) of one world's contacts; a slot without a contact has dist > 0.

    MJX-JAX: its contact slots (MJX 3.17 moved `contact` to `_impl`). Warp: the contact pool
    is shared by all worlds, so this world's contacts are found through its constraint rows
    (`efc.id` is the contact of a contact row; a contact appears once per row, which the
    any/min reductions of the tasks do not mind); other rows get dist +inf.
    """
    impl = getattr(data, "_impl", None)
    if impl is None or not hasattr(impl, "contact__dist"):
        contact = getattr(impl, "contact", None) if impl is not None else None
        contact = data.contact if contact is None else contact
        return contact.dist, contact.geom
    if impl.contact__dist.shape[0] == 0:
        raise ValueError("this mjx.Data has no Warp contact pool; attach_pool it first")
    rows = jnp.arange(impl.efc__type.shape[-1])
    live = (rows < impl.nefc) & jnp.isin(impl.efc__type, jnp.asarray(_CONTACT_ROWS))
    conid = jnp.clip(impl.efc__id, 0, impl.contact__dist.shape[0] - 1)
    dist = jnp.where(live, impl.contact__dist[conid], jnp.inf)
    return dist, impl.contact__geom[conid]


def raise_on_overflow(count: Any, where: str, buffers: WarpBuffers | None = None) -> None:
    """Raises a one-line RuntimeError when `count` (steps that overflowed) is non-zero."""
    total = float(np.sum(np.asarray(count)))
    if total <= 0:
        return
    sizes = (
        f" (naconmax {buffers.naconmax} = {buffers.nconmax} per world, njmax {buffers.njmax})"
        if buffers is not None
        else ""
    )
    raise RuntimeError(
        f"Warp contact/constraint buffer too small{sizes}: {total:g} step(s) {where} dropped "
        "contacts or constraints; raise Physics.margin or num_worlds (all envs x seeds)"
    )


__all__ = [
    "BUFFER_OVERFLOW", "IMPLS", "OVERFLOW_METRIC", "Physics", "Simulator", "WarpBuffers",
    "budget_full", "check_impl", "contact_arrays", "contact_budget", "contact_profile",
    "overflow_names", "raise_on_overflow", "warp_buffers", "warp_unavailable",
]  # fmt: skip
