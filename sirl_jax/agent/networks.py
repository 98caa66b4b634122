"""TD-MPC2 network blocks and modules (spec §1), flax linen with explicit params pytrees.

NormedLinear = Dense -> (Dropout) -> LayerNorm(eps 1e-5) -> activation. Kernels use PyTorch's
`trunc_normal_(std=0.02)`: cut at +-2 absolute = +-100 std (flax's default cut at +-2 std would
shrink the std to 0.0176), biases 0, LayerNorm 1/0. The last Dense of the reward and Q heads
is zero-initialised; the termination head's (episodic only) is not, as in the reference, where
only the reward and Q output layers are zeroed after the global trunc-normal init.
The Q ensemble is one member module whose params are stacked on a leading [num_q] axis and
applied with jax.vmap, so any subset of members (e.g. the random pair) can be gathered and run.
"""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from sirl_jax.agent.config import AgentConfig

KERNEL_INIT = nn.initializers.truncated_normal(stddev=0.02, lower=-100.0, upper=100.0)


def simnorm(x: jax.Array, group: int = 8) -> jax.Array:
    """Softmax within consecutive groups of `group` along the last axis ([..., Z] -> [..., Z])."""
    shape = x.shape
    x = x.reshape(*shape[:-1], shape[-1] // group, group)
    return jax.nn.softmax(x, axis=-1).reshape(shape)


class NormedLinear(nn.Module):
    """Dense -> Dropout (rate > 0 only) -> LayerNorm -> act ('mish' | 'simnorm')."""

    features: int
    act: str = "mish"
    dropout: float = 0.0
    simnorm_dim: int = 8

    @nn.compact
    def __call__(self, x: jax.Array, deterministic: bool = True) -> jax.Array:
        x = nn.Dense(self.features, kernel_init=KERNEL_INIT)(x)
        if self.dropout > 0:
            x = nn.Dropout(self.dropout)(x, deterministic=deterministic)
        x = nn.LayerNorm(epsilon=1e-5)(x)
        if self.act == "simnorm":
            return simnorm(x, self.simnorm_dim)
        return jax.nn.mish(x)


class MLP(nn.Module):
    """Hidden NormedLinear(Mish) layers, then a plain Dense or a NormedLinear with SimNorm.

    Attributes:
      hidden: hidden widths.
      out: output width.
      simnorm_out: the last layer is NormedLinear + SimNorm (encoder, dynamics).
      dropout: rate of the first layer's dropout (Q heads only).
      zero_last: zero-initialise the last Dense kernel (reward and Q heads).
    """

    hidden: Sequence[int]
    out: int
    simnorm_out: bool = False
    dropout: float = 0.0
    zero_last: bool = False
    simnorm_dim: int = 8

    @nn.compact
    def __call__(self, x: jax.Array, deterministic: bool = True) -> jax.Array:
        for i, width in enumerate(self.hidden):
            rate = self.dropout if i == 0 else 0.0
            x = NormedLinear(width, dropout=rate, simnorm_dim=self.simnorm_dim)(x, deterministic)
        if self.simnorm_out:
            return NormedLinear(self.out, act="simnorm", simnorm_dim=self.simnorm_dim)(x)
        init = nn.initializers.zeros if self.zero_last else KERNEL_INIT
        return nn.Dense(self.out, kernel_init=init)(x)


def make_modules(cfg: AgentConfig, action_size: int) -> dict[str, MLP]:
    """The modules of the world model + policy prior, keyed like the params dict.

    'termination' (z -> mlp_dim -> mlp_dim -> 1 logit) exists only when cfg.episodic.
    """
    arch = cfg.arch
    enc_hidden = [arch.enc_dim] * max(arch.num_enc_layers - 1, 1)
    mlp2 = [arch.mlp_dim, arch.mlp_dim]
    sd = cfg.simnorm_dim
    mods = {
        "encoder": MLP(enc_hidden, arch.latent_dim, simnorm_out=True, simnorm_dim=sd),
        "dynamics": MLP(mlp2, arch.latent_dim, simnorm_out=True, simnorm_dim=sd),
        "reward": MLP(mlp2, cfg.num_bins, zero_last=True),
        "policy": MLP(mlp2, 2 * action_size),
        "q": MLP(mlp2, cfg.num_bins, dropout=cfg.dropout, zero_last=True),
    }
    if cfg.episodic:
        mods["termination"] = MLP(mlp2, 1)
    return mods


def init_params(cfg: AgentConfig, obs_size: int, action_size: int, key: jax.Array) -> dict:
    """Initial params {'encoder', 'dynamics', 'reward', 'policy', 'qs'}; 'qs' is [num_q, ...].

    With cfg.episodic a 'termination' entry is added, from its own key fold_in(key, 5), so the
    other modules get the same values as in the non-episodic init.
    """
    mods = make_modules(cfg, action_size)
    z = jnp.zeros((1, cfg.arch.latent_dim))
    za = jnp.zeros((1, cfg.arch.latent_dim + action_size))
    k_enc, k_dyn, k_rew, k_pi, k_q = jax.random.split(key, 5)
    q_keys = jax.random.split(k_q, cfg.arch.num_q)
    params = {
        "encoder": mods["encoder"].init(k_enc, jnp.zeros((1, obs_size)))["params"],
        "dynamics": mods["dynamics"].init(k_dyn, za)["params"],
        "reward": mods["reward"].init(k_rew, za)["params"],
        "policy": mods["policy"].init(k_pi, z)["params"],
        "qs": jax.vmap(lambda k: mods["q"].init(k, za)["params"])(q_keys),
    }
    if cfg.episodic:
        params["termination"] = mods["termination"].init(jax.random.fold_in(key, 5), z)["params"]
    return params


def policy_fn(cfg: AgentConfig, action_size: int, params: dict):
    """obs [..., O] -> tanh(mu) [..., A], the prior's mean action (`act_policy`, eval mode),
    with no random op (what `export` converts to ONNX)."""
    mods = make_modules(cfg, action_size)
    enc, pi = {"params": params["encoder"]}, {"params": params["policy"]}

    def policy(obs):
        mu, _ = jnp.split(mods["policy"].apply(pi, mods["encoder"].apply(enc, obs)), 2, axis=-1)
        return jnp.tanh(mu)

    return policy


def count_params(tree) -> int:
    """Number of scalars in a params pytree (works on jax.eval_shape outputs)."""
    return int(sum(x.size for x in jax.tree_util.tree_leaves(tree)))
