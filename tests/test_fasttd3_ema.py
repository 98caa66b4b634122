"""`fasttd3.actor_ema`: the averaged actor that acts, is evaluated and is exported, by hand."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent.fasttd3 import export_params
from tests.test_fasttd3 import A, O, _agent, _batch


@pytest.mark.timeout(300)
def test_averaged_actor_follows_the_trained_one_and_acts():
    key, r_max = jax.random.PRNGKey(0), jnp.float32(40.0)
    plain, ema = _agent(beta=1.0), _agent(beta=1.0, actor_ema=0.25)
    s0_plain, s0 = plain.init(key), ema.init(key)
    # Off (FastTD3): no averaged copy in the state; on: it starts as the trained actor.
    assert "actor_ema" not in s0_plain.params
    jax.tree.map(np.testing.assert_array_equal, s0.params["actor_ema"], s0.params["actor"])

    update = jax.jit(ema.update)
    state, expected = s0, s0.params["actor"]
    for i in range(3):
        state, _ = update(state, _batch(jax.random.PRNGKey(10 + i)), r_max, key)
        # By hand: ema <- 0.75 ema + 0.25 actor, after each actor update.
        expected = jax.tree.map(lambda e, a: 0.75 * e + 0.25 * a, expected, state.params["actor"])
        jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, rtol=1e-6, atol=1e-7),
                     state.params["actor_ema"], expected)  # fmt: skip
    # The average lags the trained actor, which itself learns exactly as without it.
    s_plain, _ = jax.jit(plain.update)(s0_plain, _batch(jax.random.PRNGKey(10)), r_max, key)
    s_one, _ = update(s0, _batch(jax.random.PRNGKey(10)), r_max, key)
    jax.tree.map(np.testing.assert_array_equal, s_plain.params["actor"], s_one.params["actor"])
    kernel = lambda p: np.asarray(p["out"]["kernel"])  # noqa: E731
    assert not np.allclose(kernel(state.params["actor_ema"]), kernel(state.params["actor"]))

    # Acting, evaluation and export all read the averaged actor.
    obs = jax.random.normal(jax.random.PRNGKey(3), (4, O))
    swapped = state.replace(params={"actor": state.params["actor_ema"],
                                    "critic": state.params["critic"]})  # fmt: skip
    eval_action = ema.act_policy(state, obs, key, eval_mode=True)
    np.testing.assert_array_equal(eval_action, plain.act_policy(swapped, obs, key, True))
    assert eval_action.shape == (4, A)
    exported = export_params(state)
    assert "actor_ema" not in exported
    jax.tree.map(np.testing.assert_array_equal, exported["actor"], state.params["actor_ema"])


def test_actor_ema_out_of_range_is_refused():
    from sirl_jax.agent.fasttd3_config import FastTD3Config

    with pytest.raises(ValueError, match="fasttd3.actor_ema.*1.5.*in \\[0, 1\\]"):
        FastTD3Config(actor_ema=1.5)
