"""Policies built from rules: one rule per robot, or a chooser that picks a rule first."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pnp_twin.policies.rules import NAMED_RULES as RULES
from pnp_twin.twin.decision import Decision, RobotSpec


class RuleChoosingPolicy:
    """A policy that first picks a rule for the deciding robot, then lets the rule pick.

    Subclasses override :meth:`select_rule`; this is the shape of the HDQN meta-controller.
    The chosen rule's name is :attr:`last_rule` (the line counts decisions per rule by it).
    """

    name = "rule-choosing"

    def __init__(self) -> None:
        self.robots: list[RobotSpec] = []
        self.rng = np.random.default_rng(0)
        self.last_rule: str | None = None

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.robots = list(robots)
        self.rng = rng
        self.last_rule = None

    def select_rule(self, decision: Decision) -> str:
        raise NotImplementedError

    def choose(self, decision: Decision) -> int:
        rule = self.select_rule(decision)
        self.last_rule = rule
        return RULES[rule](decision, self.rng)


class RuleMix(RuleChoosingPolicy):
    """A fixed rule per robot: ``RuleMix(["SPT", "SPT", "SPT", "FIFO"])``, or one for all."""

    def __init__(self, rules: Sequence[str]) -> None:
        super().__init__()
        self.rules = [r.upper() for r in rules]
        self.name = self.rules[0] if len(set(self.rules)) == 1 else ",".join(self.rules)

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        super().reset(robots, rng)
        if len(self.rules) == 1:
            self.rules = self.rules * len(robots)
        elif len(self.rules) != len(robots):
            raise ValueError(
                f"policy: the mix {','.join(self.rules)} names {len(self.rules)} rules for "
                f"{len(robots)} robots; give one rule or one per robot"
            )

    def select_rule(self, decision: Decision) -> str:
        return self.rules[decision.robot]

    def fixed_rules(self) -> list[str] | None:
        """The rule per robot (after ``reset``), for engines that apply rules themselves
        (:func:`~pnp_twin.twin.decision.fixed_rules`); None for a subclass that chooses
        otherwise."""
        cls = type(self)
        plain = cls.select_rule is RuleMix.select_rule and cls.choose is RuleMix.choose
        return list(self.rules) if plain else None


class SettableRules(RuleMix):
    """A rule per robot that a driver (an RL environment) sets before each decision."""

    def __init__(self, n_robots: int, default: str = "FIFO") -> None:
        super().__init__([default] * n_robots)
        self.name = "external"

    def set(self, robot: int, rule: str) -> None:
        self.rules[robot] = rule

    def fixed_rules(self) -> list[str] | None:
        return None  # the rules change between decisions
