"""The decision record the gateway hands to a policy, and the policy protocol.

The twin never imports a policy: it builds a :class:`Decision` (plain data) whenever a free
robot has candidates and asks the policy object for the index of the part to pick. A policy
that chooses by a named rule says which in a ``last_rule`` attribute (read right after
``choose``); the KPIs count decisions per rule, "?" for policies without one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True, slots=True)
class RobotSpec:
    """What a policy may know about the robot that decides (all SI units)."""

    index: int  # 0-based, upstream first
    count: int  # robots on the line
    workspace: tuple[float, float]  # [a, b] along the belt, m
    bin: tuple[float, float]  # place target (x, y), m
    arm_speed: float  # m/s
    acceleration: float  # m/s^2, 0 = none
    pick_time: float  # s
    place_time: float  # s
    belt_speed: float  # m/s
    belt_width: float  # m
    side: str = "upper"  # upper, lower or over (scenario robots.side)
    reach: float = 0.0  # m from ``mount``; 0: no limit
    mount: tuple[float, float] = (0.0, 0.0)  # the base, where the reach is measured from
    picks: tuple[bool, ...] = ()  # per kind code: whether it picks that kind; (): every kind
    pick_times: tuple[float, ...] = ()  # per kind code, s; (): pick_time for every kind
    place_times: tuple[float, ...] = ()  # per kind code, s; (): place_time for every kind
    values: tuple[float, ...] = ()  # per kind code, the value of a part; (): 1 each

    def pick_of(self, kind: int) -> float:
        """Grip time of a part of kind code ``kind``."""
        return self.pick_times[kind] if self.pick_times else self.pick_time

    def place_of(self, kind: int) -> float:
        """Release time of a part of kind code ``kind``."""
        return self.place_times[kind] if self.place_times else self.place_time

    def value_of(self, kind: int) -> float:
        """Value of a part of kind code ``kind``."""
        return self.values[kind] if self.values else 1.0

    @property
    def bin_side(self) -> float:
        """+1 when the bin is on the upper side of the belt's centre line, -1 below it: SD
        prefers parts nearer the bin's edge, LD the far edge."""
        return 1.0 if self.bin[1] >= self.belt_width / 2.0 else -1.0


class Decision:
    """One free robot's choice among candidates, at one instant.

    Candidates are listed furthest downstream first (the order they entered the
    workspace). ``xs``/``ys`` are the parts' positions now, ``times`` the interception
    times from the tool position ``tool``, ``kinds`` their kind codes (indices into the
    scenario's feeder.kinds; all 0 on a line of one kind). A decision is read only: the
    answer is the index ``choose`` returns.
    """

    __slots__ = ("robot", "spec", "time", "tool", "parts", "xs", "ys", "times", "kinds")

    def __init__(
        self,
        spec: RobotSpec,
        time: float,
        tool: tuple[float, float],
        parts: list[int],
        xs: list[float],
        ys: list[float],
        times: list[float],
        kinds: list[int] | None = None,
    ) -> None:
        self.robot = spec.index
        self.spec = spec
        self.time = time
        self.tool = tool
        self.parts = parts
        self.xs = xs
        self.ys = ys
        self.times = times
        self.kinds = [0] * len(parts) if kinds is None else kinds

    def __len__(self) -> int:
        return len(self.parts)

    def __repr__(self) -> str:
        return f"Decision(robot={self.robot}, time={self.time:.4f}, candidates={len(self.parts)})"


@runtime_checkable
class Policy(Protocol):
    """Anything with ``reset`` and ``choose`` can drive the line (optionally ``last_rule``:
    the name of the rule behind the last choice; ``attach(belt)``, called once the
    line's belt is loaded, for policies that look at the belt; ``bind_run(scenario, seed,
    duration)``, called after ``reset``, for policies that simulate the run themselves (the
    lookahead controller); and ``fixed_rules()``, see :func:`fixed_rules`)."""

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        """Called once before a run with the robots and the run's policy stream."""

    def choose(self, decision: Decision) -> int | None:
        """Index into ``decision.parts`` of the part to pick (there is at least one), or
        None to pick nothing now: the robot takes a NooP (a balancing controller's robot
        that owns no candidate)."""
        ...


def fixed_rules(policy: object) -> list[str] | None:
    """The built-in rule of each robot, when the policy (after its ``reset``) always picks as
    those rules do, so an engine may apply them itself instead of asking; else None.

    A policy opts in with a ``fixed_rules()`` method returning the names (a rule mix); the
    core recognises no class by name.
    """
    method = getattr(policy, "fixed_rules", None)
    if method is None:
        return None
    names = method()
    return None if names is None else [str(n) for n in names]
