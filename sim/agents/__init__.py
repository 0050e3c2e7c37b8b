"""Cohabitants: pedestrians, vulnerable road users and robots on sidewalks (ORCA), and vehicles on roads (IDM)."""

from sim.agents.crowd import AGENT_DEFAULTS, AGENT_DTYPE, AgentManager, EgoState
from sim.agents.kinds import AGENT_KINDS, DEFAULT_MIX, KIND_NAMES, MOVEMENTS, AgentKind, agent_kind

__all__ = [
    "AGENT_DEFAULTS",
    "AGENT_DTYPE",
    "AGENT_KINDS",
    "DEFAULT_MIX",
    "KIND_NAMES",
    "MOVEMENTS",
    "AgentKind",
    "AgentManager",
    "EgoState",
    "agent_kind",
]
