"""The per-run scalars (`sirl_jax.agent.hyper`): each sweepable field is read from the state,
not traced into the program, and each value does what its field says."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent
from sirl_jax.agent.fasttd3_config import FastTD3Config
from sirl_jax.agent.hyper import SWEEPABLE, fields, get, init_hyper, with_hyper
from sirl_jax.sweep import Sweep, _replace
from sirl_jax.types import Batch

O, A, T, H, B = 6, 3, 50, 3, 8
R_MAX = jnp.float32(40.0)
LR = 1e-30  # a learning rate that moves nothing visible (zero is refused)
TINY_FASTTD3 = FastTD3Config(actor_hidden_dim=16, critic_hidden_dim=16, num_atoms=11,
                             batch_size=B, policy_frequency=2)  # fmt: skip


def _cfg(kind: str) -> AgentConfig:
    if kind == "fasttd3":
        return AgentConfig(kind="fasttd3", fasttd3=TINY_FASTTD3,
                           sirl=SirlConfig(bc_form="mse_mean"))  # fmt: skip
    return AgentConfig.tiny()


def _batch(kind: str) -> Batch:
    n, rows = (1, 2 * B) if kind == "fasttd3" else (H, B)
    k = jax.random.split(jax.random.PRNGKey(1), 4)
    return Batch(obs=jax.random.normal(k[0], (n + 1, rows, O)),
                 action=jnp.tanh(jax.random.normal(k[1], (n, rows, A))),
                 reward=jax.random.uniform(k[2], (n, rows)), terminated=jnp.zeros((n, rows)),
                 episode_return=jax.random.uniform(k[3], (rows,), maxval=50.0))  # fmt: skip


def _setup(kind: str):
    """(config, batch, agent, its initial state, its jitted update) of `kind`'s tiny learner."""
    cfg, batch = _cfg(kind), _batch(kind)
    agent = make_agent(cfg, O, A, T)
    return cfg, batch, agent, jax.jit(agent.init)(jax.random.PRNGKey(0)), jax.jit(agent.update)


def _program(agent, state, batch):
    """The traced update of `agent` from `state`, and FastTD3's acting (it reads the noise
    bounds; TD-MPC2's planner reads no per-run scalar): jaxpr text and its constants."""
    programs = [(agent.update, (state, batch, R_MAX, jax.random.PRNGKey(2)))]
    if agent.cfg.kind == "fasttd3":
        obs, first = batch.obs[0, :4], jnp.ones(4, bool)
        programs.append((agent.act, (state, agent.init_planner(4), obs, first,
                                     jax.random.PRNGKey(3))))  # fmt: skip
    out = []
    for fn, args in programs:
        closed = jax.make_jaxpr(fn)(*args)
        out.append((str(closed.jaxpr), [np.asarray(c) for c in closed.consts
                                        if hasattr(c, "shape")]))  # fmt: skip
    return out


def _other(cfg: AgentConfig, field: str) -> AgentConfig:
    """`cfg` with `field` set to another valid value."""
    value = get(cfg, field)
    new = 0.0 if field == "fasttd3.std_min" else value * 0.5 + 0.125 * (field == "sirl.beta")
    return _replace(cfg, field.split("."), new)


@pytest.mark.timeout(300)
@pytest.mark.parametrize("kind", ["tdmpc2", "fasttd3"])
def test_a_sweepable_field_changes_the_state_and_not_the_program(kind):
    cfg, batch = _cfg(kind), _batch(kind)
    base = make_agent(cfg, O, A, T)
    state = jax.jit(base.init)(jax.random.PRNGKey(0))
    reference = _program(base, state, batch)
    assert fields(kind), kind
    for field in fields(kind):
        other_cfg = _other(cfg, field)
        assert get(other_cfg, field) != get(cfg, field)
        other = make_agent(other_cfg, O, A, T)
        program = _program(other, with_hyper(state, other_cfg), batch)
        for (text, consts), (ref_text, ref_consts) in zip(program, reference, strict=True):
            assert text == ref_text, f"{field} is traced into {kind}'s program"
            assert len(consts) == len(ref_consts)
            for c, r in zip(consts, ref_consts, strict=True):
                np.testing.assert_array_equal(c, r, err_msg=f"{field} is a constant of it")
        changed = [k for k, v in init_hyper(other_cfg).items() if v != state.hyper[k]]
        assert changed and all(k.startswith(field.replace(".", "_")) or k == "enc_lr"
                               for k in changed), (field, changed)  # fmt: skip


@pytest.mark.timeout(300)
def test_fasttd3_values_do_what_their_fields_say():
    cfg, batch, agent, state, update = _setup("fasttd3")

    def with_values(**values):
        f = dataclasses.replace(cfg.fasttd3, **values)
        return with_hyper(state, dataclasses.replace(cfg, fasttd3=f))

    def moved(a, b):
        """The largest change of any parameter."""
        return max(float(np.max(np.abs(x - y))) for x, y in
                   zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True))  # fmt: skip

    same = lambda a, b: jax.tree.all(jax.tree.map(np.array_equal, a, b))
    # a rate of 1e-30 with no decay: AdamW moves that network by at most a few lr (its steps
    # are g / (|g| + eps) <= 1 at first), the other one by its own rate's steps
    new, _ = update(with_values(actor_lr=LR, weight_decay=0.0), batch, R_MAX,
                    jax.random.PRNGKey(2))  # fmt: skip
    assert moved(new.params["actor"], state.params["actor"]) <= 4 * LR
    assert moved(new.params["critic"], state.params["critic"]) > 1e-5
    new, _ = update(with_values(critic_lr=LR, weight_decay=0.0), batch, R_MAX,
                    jax.random.PRNGKey(2))  # fmt: skip
    assert moved(new.params["critic"], state.params["critic"]) <= 4 * LR
    assert moved(new.params["actor"], state.params["actor"]) > 1e-5
    # tau 1: the target critic is the updated critic
    new, _ = update(with_values(tau=1.0), batch, R_MAX, jax.random.PRNGKey(2))
    assert same(new.target_critic, new.params["critic"])
    # std_min = std_max: every env acts with exactly that noise std
    act = jax.jit(agent.act)
    obs, first = batch.obs[0, :5], jnp.ones(5, bool)
    _, noise = act(with_values(std_min=0.25, std_max=0.25), agent.init_planner(5), obs, first,
                   jax.random.PRNGKey(4))  # fmt: skip
    np.testing.assert_array_equal(noise.std, np.full((5, 1), 0.25, np.float32))


@pytest.mark.timeout(300)
def test_tdmpc2_rate_zero_freezes_the_networks_and_tau_one_copies_the_qs():
    cfg, batch, agent, state, update = _setup("tdmpc2")
    frozen = with_hyper(state, dataclasses.replace(cfg, lr=LR, tau=1.0))
    new, _ = update(frozen, batch, R_MAX, jax.random.PRNGKey(2))
    # Adam's first step moves each parameter by at most about lr (g / (|g| + eps) <= 1)
    for a, b in zip(jax.tree.leaves(new.params), jax.tree.leaves(state.params), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=LR)
    for a, b in zip(jax.tree.leaves(new.target_qs), jax.tree.leaves(new.params["qs"]),
                    strict=True):  # fmt: skip
        np.testing.assert_array_equal(a, b)
    moved, _ = update(state, batch, R_MAX, jax.random.PRNGKey(2))
    assert not np.array_equal(jax.tree.leaves(moved.params)[0], jax.tree.leaves(state.params)[0])


def test_a_field_the_learner_does_not_read_is_refused_in_one_line():
    from sirl_jax.presets import get_preset

    with pytest.raises(Exception) as e:
        Sweep.parse(1, ["fasttd3.actor_lr=1e-4,3e-4"]).configs(get_preset("smoke"))
    message = str(e.value)
    assert "cannot be swept with agent.kind=tdmpc2" in message and "\n" not in message
    assert "allowed for tdmpc2: sirl.beta, lr" in message
    # every sweepable field names a learner that reads it
    assert all(kinds and set(kinds) <= {"tdmpc2", "fasttd3"} for kinds, _ in SWEEPABLE.values())
