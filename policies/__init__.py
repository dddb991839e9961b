"""Dispatching policies: the classic rules, rule mixes and the learned HDQN."""

from pnp_twin.policies.base import RuleChoosingPolicy, RuleMix, SettableRules
from pnp_twin.policies.registry import PolicyError, make_policy
from pnp_twin.policies.rules import PAPER_RULES, RULES

__all__ = [
    "PAPER_RULES",
    "RULES",
    "PolicyError",
    "RuleChoosingPolicy",
    "RuleMix",
    "SettableRules",
    "make_policy",
]
