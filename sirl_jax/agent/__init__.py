"""TD-MPC2 world model, losses with the TDMPBC self-imitative term, and the MPPI planner."""

from sirl_jax.agent.agent import Agent, AgentState
from sirl_jax.agent.config import AgentConfig, SirlConfig
from sirl_jax.agent.factory import make_agent
from sirl_jax.agent.planner import PlannerState

__all__ = ["Agent", "AgentConfig", "AgentState", "PlannerState", "SirlConfig", "make_agent"]
