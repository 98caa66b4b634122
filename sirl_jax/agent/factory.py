"""`make_agent`: the learner `AgentConfig.kind` names, TD-MPC2 or FastTD3, as an `Agent`."""

from __future__ import annotations

from sirl_jax.agent.agent import Agent, make_tdmpc2
from sirl_jax.agent.config import AgentConfig
from sirl_jax.agent.fasttd3 import make_fasttd3


def make_agent(cfg: AgentConfig, obs_size: int, action_size: int, episode_length: int,
               success_bar: float | None = None) -> Agent:  # fmt: skip
    """Builds the agent of `cfg.kind` for static sizes (`make_tdmpc2`, `make_fasttd3`).

    success_bar: the task's R_target; required when `cfg.sirl.g_source == "target"`.
    """
    make = make_fasttd3 if cfg.kind == "fasttd3" else make_tdmpc2
    return make(cfg, obs_size, action_size, episode_length, success_bar)
