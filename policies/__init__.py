"""Dispatching policies: the classic rules, rule mixes and the learned HDQN."""

from policies.base import RuleChoosingPolicy, RuleMix, SettableRules
from policies.registry import PolicyError, make_policy
from policies.rules import PAPER_RULES, RULES

__all__ = [
    "PAPER_RULES",
    "RULES",
    "PolicyError",
    "RuleChoosingPolicy",
    "RuleMix",
    "SettableRules",
    "make_policy",
]
