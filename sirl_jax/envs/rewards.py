"""dm_control's `rewards.tolerance` in JAX, and the terms HumanoidBench's locomotion rewards share.

Every function is pure and jittable; bounds, margins and sigmoids are static Python floats and
strings (they are constants of each task), the measured quantities are arrays. Constants and
formulas follow HumanoidBench (spec: humanoidbench.md §3).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

STAND_HEIGHT = 1.65
"""HumanoidBench `_STAND_HEIGHT`: head height (m) above which `standing` is 1."""
CRAWL_HEIGHT = 0.8
WALK_SPEED = 1.0
RUN_SPEED = 5.0

_SIGMOIDS = ("gaussian", "linear", "quadratic")


def _sigmoid(d: jax.Array, value_at_margin: float, sigmoid: str) -> jax.Array:
    """dm_control `_sigmoids`: normalised distance d >= 0 -> (0, 1], value_at_margin at d = 1."""
    if sigmoid == "gaussian":
        if not 0.0 < value_at_margin < 1.0:
            raise ValueError(
                f"gaussian tolerance needs 0 < value_at_margin < 1, got {value_at_margin}"
            )
        scale = math.sqrt(-2.0 * math.log(value_at_margin))
        return jnp.exp(-0.5 * (d * scale) ** 2)
    if not 0.0 <= value_at_margin < 1.0:
        raise ValueError(
            f"{sigmoid} tolerance needs 0 <= value_at_margin < 1, got {value_at_margin}"
        )
    if sigmoid == "linear":
        scaled = d * (1.0 - value_at_margin)
        return jnp.where(jnp.abs(scaled) < 1.0, 1.0 - scaled, 0.0)
    if sigmoid == "quadratic":
        scaled = d * math.sqrt(1.0 - value_at_margin)
        return jnp.where(jnp.abs(scaled) < 1.0, 1.0 - scaled**2, 0.0)
    raise ValueError(f"unknown sigmoid {sigmoid!r}; allowed: {', '.join(_SIGMOIDS)}")


def tolerance(
    x: jax.Array,
    bounds: tuple[float, float] = (0.0, 0.0),
    margin: float = 0.0,
    sigmoid: str = "gaussian",
    value_at_margin: float = 0.1,
) -> jax.Array:
    """dm_control `rewards.tolerance`: 1 inside `bounds`, decaying with distance outside.

    Args:
      x: [...] the measured quantity.
      bounds: (lower, upper); either may be +-inf.
      margin: distance outside the bounds at which the value is `value_at_margin`; 0 makes the
        result the indicator of `bounds`.
      sigmoid: "gaussian", "linear" or "quadratic".
      value_at_margin: the value at distance `margin` from the nearest bound.

    Returns:
      [...] float32 values in [0, 1].
    """
    lower, upper = bounds
    if lower > upper:
        raise ValueError(f"tolerance bounds must satisfy lower <= upper, got {bounds}")
    if margin < 0:
        raise ValueError(f"tolerance margin must be >= 0, got {margin}")
    x = jnp.asarray(x, jnp.float32)
    in_bounds = (lower <= x) & (x <= upper)
    if margin == 0:
        return jnp.where(in_bounds, 1.0, 0.0).astype(jnp.float32)
    # The distance to the violated bound only; the other branch may be inf and is never selected.
    d = jnp.where(x < lower, lower - x, x - upper) / margin
    d = jnp.where(in_bounds, 0.0, d)
    return jnp.where(in_bounds, 1.0, _sigmoid(d, value_at_margin, sigmoid)).astype(jnp.float32)


def standing(head_z: jax.Array, height: float = STAND_HEIGHT) -> jax.Array:
    """tol(head_z, (height, inf), margin height/4), gaussian."""
    return tolerance(head_z, (height, math.inf), margin=height / 4)


def upright(zz: jax.Array, bound: float = 0.9, margin: float = 1.9) -> jax.Array:
    """tol(torso zz, (bound, inf), margin, linear, value_at_margin 0)."""
    return tolerance(zz, (bound, math.inf), margin=margin, sigmoid="linear", value_at_margin=0.0)


def small_control(actuator_force: jax.Array) -> jax.Array:
    """(4 + mean_i tol(f_i, (0, 0), margin 10, quadratic, vam 0)) / 5, in [0.8, 1].

    Args:
      actuator_force: [nu] `data.actuator_force`.
    """
    per = tolerance(actuator_force, margin=10.0, sigmoid="quadratic", value_at_margin=0.0)
    return (4.0 + jnp.mean(per)) / 5.0


def move(v_x: jax.Array, speed: float) -> jax.Array:
    """(5 m + 1) / 6 with m = tol(v_x, (speed, inf), margin speed, linear, vam 0), in [1/6, 1]."""
    if speed <= 0:
        raise ValueError(f"move speed must be > 0, got {speed}")
    m = tolerance(v_x, (speed, math.inf), margin=speed, sigmoid="linear", value_at_margin=0.0)
    return (5.0 * m + 1.0) / 6.0


def dont_move(v_xy: jax.Array) -> jax.Array:
    """mean over x, y of tol(v, (0, 0), margin 2), gaussian. v_xy: [2] CoM velocity."""
    return jnp.mean(tolerance(v_xy, margin=2.0))


def any_contact(
    dist: jax.Array, geom: jax.Array, mask_a: jax.Array, mask_b: jax.Array | None = None
) -> jax.Array:
    """Whether an active contact touches a geom in `mask_a` (and, if given, one in `mask_b`).

    MJX keeps a slot for every candidate pair; a slot is an active contact when `dist < 0`
    (margins are 0 in these scenes), the counterpart of HumanoidBench scanning `data.contact`.

    Args:
      dist: [C] `data.contact.dist`.
      geom: [C, 2] int `data.contact.geom`.
      mask_a: [ngeom] bool, geoms of interest.
      mask_b: [ngeom] bool or None; if given the other geom of the pair must be in it.

    Returns:
      [] bool.
    """
    if dist.shape[0] == 0:
        return jnp.zeros((), bool)
    g1, g2 = geom[:, 0], geom[:, 1]
    if mask_b is None:
        hit = mask_a[g1] | mask_a[g2]
    else:
        hit = (mask_a[g1] & mask_b[g2]) | (mask_a[g2] & mask_b[g1])
    return jnp.any(hit & (dist < 0))
