"""Config defaults, presets, derived values and validation messages."""

import dataclasses

import pytest

from sirl_jax.agent import AgentConfig, SirlConfig, make_agent


@pytest.mark.timeout(30)
def test_defaults_match_spec():
    c = AgentConfig()
    assert (c.horizon, c.num_samples, c.num_elites, c.num_pi_trajs, c.iterations) == (
        3,
        512,
        64,
        24,
        6,
    )
    assert (c.temperature, c.min_std, c.max_std, c.rho) == (0.5, 0.05, 2.0, 0.5)
    assert (c.consistency_coef, c.reward_coef, c.value_coef, c.entropy_coef) == (20, 0.1, 0.1, 1e-4)
    assert (c.tau, c.lr, c.enc_lr_scale, c.grad_clip_norm, c.pi_adam_eps) == (
        0.01,
        3e-4,
        0.3,
        20.0,
        1e-5,
    )
    assert (c.batch_size, c.num_bins, c.vmin, c.vmax, c.dropout) == (256, 101, -10, 10, 0.01)
    assert c.arch == (256, 512, 512, 2, 5)
    assert c.mpc and not c.episodic and c.entropy_form == "scaled"
    assert c.termination_coef == 1.0
    s = c.sirl
    assert (s.enabled, s.beta, s.bc_form, s.g_source, s.return_kind) == (
        True,
        1.0,
        "loglik",
        "rmax",
        "undiscounted",
    )


@pytest.mark.timeout(30)
def test_presets_and_overrides():
    assert AgentConfig(model_size="317M").arch.num_q == 8
    assert AgentConfig(model_size="1M").arch.num_q == 2
    c = AgentConfig(model_size="19M", mlp_dim=64)
    assert c.arch.mlp_dim == 64 and c.arch.enc_dim == 1024 and c.mlp_dim == 64
    assert AgentConfig.tiny().arch.latent_dim == 32
    assert AgentConfig.small().arch == (64, 128, 64, 2, 2)  # enc, mlp, latent, layers, Qs
    assert AgentConfig.small(num_q=None).arch.num_q == 5  # an override replaces the field


@pytest.mark.timeout(30)
def test_derived_values_not_written_back():
    c = AgentConfig.tiny()
    a61 = make_agent(c, obs_size=151, action_size=61, episode_length=1000)
    a19 = make_agent(c, obs_size=51, action_size=19, episode_length=500)
    assert a61.iterations == c.iterations + 2 and a19.iterations == c.iterations
    assert a61.discount == pytest.approx(0.995) and a19.discount == pytest.approx(0.99)
    assert make_agent(dataclasses.replace(c, discount=0.9), 5, 2, 1000).discount == 0.9
    assert c.iterations == 2 and c.discount is None


@pytest.mark.timeout(30)
@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(model_size="7M"), "model_size"),
        (dict(horizon=0), "horizon"),
        (dict(num_elites=600), "num_elites"),
        (dict(num_pi_trajs=512), "num_pi_trajs"),
        (dict(min_std=3.0), "min_std"),
        (dict(lr=0.0), "lr"),
        (dict(batch_size=0), "batch_size"),
        (dict(entropy_form="sac"), "entropy_form"),
        (dict(latent_dim=100), "latent_dim"),
        (dict(num_q=1), "num_q"),
        (dict(rho=0.0), "rho"),
        (dict(plan_env_chunk=-1), "plan_env_chunk"),
        (dict(termination_coef=-1.0), "termination_coef"),
    ],
)
def test_validation_names_field(kwargs, field):
    with pytest.raises(ValueError, match=field) as e:
        AgentConfig(**kwargs)
    assert repr(next(iter(kwargs.values()))) in str(e.value) and "allowed" in str(e.value)


@pytest.mark.timeout(30)
@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(beta=-1.0), "sirl.beta"),
        (dict(bc_form="l2"), "sirl.bc_form"),
        (dict(g_source="best"), "sirl.g_source"),
        (dict(return_kind="mean"), "sirl.return_kind"),
        (dict(g_eps=0.0), "sirl.g_eps"),
    ],
)
def test_sirl_validation(kwargs, field):
    with pytest.raises(ValueError, match=field):
        SirlConfig(**kwargs)


@pytest.mark.timeout(30)
def test_make_agent_rejects_bad_sizes():
    with pytest.raises(ValueError, match="action_size"):
        make_agent(AgentConfig.tiny(), obs_size=3, action_size=0, episode_length=10)
