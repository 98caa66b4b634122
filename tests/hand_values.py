"""Hand-worked values the manipulation reward tests share: tolerance checks, a standing robot's
stand-term inputs, and dm_control's gaussian and linear sigmoids at hand-picked distances."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np


def close(a, b, tol=1e-5):
    np.testing.assert_allclose(np.asarray(a), b, rtol=tol, atol=tol)


def standing_robot():
    """head 1.7, zz 1, zero force and CoM velocity: stand terms 1, small_control 1."""
    return jnp.asarray(1.7), jnp.asarray(1.0), jnp.zeros(61), jnp.zeros(3)


def gauss_prox(d):
    """tol(d, (0, 0.2), margin 1), gaussian: 0.1 ** ((d - 0.2) ** 2) outside the bounds."""
    return 1.0 if d <= 0.2 else 0.1 ** ((d - 0.2) ** 2)


def lin(d, vam=0.1):
    """dm_control's linear sigmoid at d = distance / margin: max(1 - d (1 - vam), 0)."""
    return max(1.0 - d * (1.0 - vam), 0.0)
