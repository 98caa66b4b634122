"""Hand-worked checks of symlog, two-hot, soft cross-entropy, decoding and the discount."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import math as am

NB, LO, HI = 101, -10.0, 10.0


@pytest.mark.timeout(60)
def test_symlog_symexp_values():
    e1 = math.e - 1.0
    np.testing.assert_allclose(am.symlog(jnp.array([0.0, e1, -e1])), [0.0, 1.0, -1.0], atol=1e-6)
    np.testing.assert_allclose(am.symexp(jnp.array([0.0, 1.0, -1.0])), [0.0, e1, -e1], rtol=1e-6)
    x = jnp.array([-1234.5, -3.0, -0.01, 0.0, 0.2, 7.0, 5000.0])
    np.testing.assert_allclose(am.symexp(am.symlog(x)), x, rtol=1e-5, atol=1e-6)


@pytest.mark.timeout(60)
def test_two_hot_hand_cases():
    # symlog(x) = 0 sits exactly on bin 50 (bins are -10, -9.8, ..., 10).
    th = np.asarray(am.two_hot(jnp.array(0.0), NB, LO, HI))
    assert th[50] == pytest.approx(1.0) and th.sum() == pytest.approx(1.0)
    # symlog(x) = 0.1 is half-way between bins 50 (0.0) and 51 (0.2).
    th = np.asarray(am.two_hot(am.symexp(jnp.array(0.1)), NB, LO, HI))
    np.testing.assert_allclose(th[[50, 51]], [0.5, 0.5], atol=1e-5)
    # symlog(x) = -9.95 -> 3/4 on bin 0, 1/4 on bin 1.
    th = np.asarray(am.two_hot(am.symexp(jnp.array(-9.95)), NB, LO, HI))
    np.testing.assert_allclose(th[[0, 1]], [0.75, 0.25], atol=1e-4)
    # Top edge and beyond: all mass on bin 100; the wrapped neighbour (bin 0) gets weight 0.
    for x in (math.expm1(10.0), 1e9):
        th = np.asarray(am.two_hot(jnp.array(x, jnp.float32), NB, LO, HI))
        assert th[100] == pytest.approx(1.0, abs=1e-5) and th[0] == pytest.approx(0.0, abs=1e-5)
    th = np.asarray(am.two_hot(jnp.array(-1e9), NB, LO, HI))
    assert th[0] == pytest.approx(1.0)


@pytest.mark.timeout(60)
def test_two_hot_round_trip_at_bin_centres_and_between():
    centres = np.linspace(LO, HI, NB)
    ys = np.concatenate([centres, centres[:-1] + 0.037])
    x = am.symexp(jnp.asarray(ys, jnp.float32))
    th = am.two_hot(x, NB, LO, HI)
    np.testing.assert_allclose(th.sum(-1), 1.0, atol=1e-5)
    # Decoding log(two-hot) returns the target: expectation in symlog space, then symexp.
    back = am.decode(jnp.log(th), LO, HI)
    np.testing.assert_allclose(am.symlog(back), ys, atol=2e-4)
    # Exact centres put (almost) all mass on the nearest bin.
    assert np.all(np.asarray(th[:NB]).max(-1) > 0.999)


@pytest.mark.timeout(60)
def test_soft_ce_and_decode():
    # Two bins, logits [0, ln 3] -> log_softmax [-ln 4, ln 3 - ln 4]; target [1/2, 1/2].
    ce = am.soft_ce(jnp.array([0.0, math.log(3.0)]), jnp.array([0.5, 0.5]))
    assert float(ce) == pytest.approx(math.log(4.0) - 0.5 * math.log(3.0), rel=1e-6)
    # Uniform logits: CE against any two-hot is ln(101); decoded value is exactly 0.
    z = jnp.zeros((3, NB))
    ce = am.two_hot_ce(z, jnp.array([0.0, 5.0, -70.0]), NB, LO, HI)
    np.testing.assert_allclose(ce, math.log(NB), rtol=1e-6)
    np.testing.assert_allclose(am.decode(z, LO, HI), 0.0, atol=1e-6)


@pytest.mark.timeout(30)
def test_discount_from_episode_length():
    assert am.discount_from_episode_length(1000) == pytest.approx(0.995)
    assert am.discount_from_episode_length(500) == pytest.approx(0.99)
    for t in (1, 50, 100):
        assert am.discount_from_episode_length(t) == pytest.approx(0.95)
    assert am.discount_from_episode_length(10**6) == pytest.approx(0.995)
    with pytest.raises(ValueError, match="episode_length"):
        am.discount_from_episode_length(0)
