"""Agents: `make_agent(config)` -> `Agent` (pure init / explore / act / update functions)."""

from docrl_jax.algorithms.common import Agent, AgentState, policy_freq
from docrl_jax.algorithms.sac import make_sac
from docrl_jax.algorithms.td3 import make_td3


def make_agent(config) -> Agent:
    """td3 and ddpg share `td3.py` (ddpg = one critic, no smoothing, no delay); sac has `sac.py`."""
    return make_sac(config) if config.agent.algo == "sac" else make_td3(config)


__all__ = ["Agent", "AgentState", "make_agent", "policy_freq"]
