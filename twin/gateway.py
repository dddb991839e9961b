"""The gateway: decision events, termination schemes, and the hand-off to a policy.

Whenever a robot is free it reports to the gateway, which decides *when* it may choose
(the termination scheme) and asks the policy *what* to choose:

- ``t_continue``: each robot decides the moment it is free; the others continue.
- ``t_all``: a free robot waits until every available robot is free; then all decide, in
  robot order (upstream first), each seeing the claims of those before it.
- ``t_any``: the first free robot opens a decision epoch; every robot still on its approach
  leg is interrupted (claim released, tool stops where it is) and joins it; robots carrying
  a part finish placing first and open the next epoch when they are free.

With ``hold=True`` every epoch pauses the simulation: :attr:`pending` lists the robots that
decide and the driver (a Gymnasium or PettingZoo environment) calls :meth:`release` once it
has set the policy's answer. Without it, decisions cost no extra event under t_continue.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import simpy

from pnp_twin.twin.decision import Decision, Policy
from pnp_twin.twin.records import Recorder

SCHEMES = ("t_continue", "t_all", "t_any")


class Station(Protocol):
    """What the gateway sees of a robot (:class:`twin.robot.Robot` is one)."""

    index: int  # 0-based, upstream first
    down: bool  # broken down: not expected at a decision epoch

    def interrupt_approach(self) -> bool:
        """Stop an approach leg under way now (t_any); False when not approaching."""
        ...


class Gateway:
    """Yields decision events to a policy according to a termination scheme."""

    def __init__(
        self,
        env: simpy.Environment,
        scheme: str,
        policy: Policy,
        recorder: Recorder,
        hold: bool = False,
    ) -> None:
        if scheme not in SCHEMES:
            raise ValueError(f"termination: {scheme!r} is not a scheme; allowed {SCHEMES}")
        self.env = env
        self.scheme = scheme
        self.policy = policy
        self.recorder = recorder
        self.hold = hold
        self.robots: Sequence[Station] = []
        self.waiting: dict[int, simpy.Event] = {}  # robot index -> its release event
        self.expected: set[int] = set()  # t_any: robots the open epoch waits for
        self.pending: list[int] = []  # robots of the epoch the driver must answer
        self.held: dict[int, simpy.Event] = {}  # hold mode: their release events
        self.epochs = 0

    @property
    def decides_at_once(self) -> bool:
        """True when a free robot never waits for an epoch (t_continue without hold), so it
        need not report :meth:`free` at all."""
        return self.scheme == "t_continue" and not self.hold

    # -- called by robots --------------------------------------------------------------------
    def free(self, robot: Station) -> simpy.Event | None:
        """A robot is free: None to decide now, or an event to wait for."""
        if self.scheme == "t_continue" and not self.hold:
            return None
        event = self.env.event()
        self.waiting[robot.index] = event
        if self.scheme == "t_continue":
            self._open([robot.index])
        elif self.scheme == "t_all":
            self._maybe_all()
        else:
            self._join_any(robot)
        return event

    def choose(self, robot: Station, decision: Decision) -> tuple[int | None, str | None]:
        """The policy's answer: (index of the candidate, name of the rule behind it or None);
        (None, None) when the policy picks nothing now (the robot takes a NooP, which the
        robot records).

        A policy names its rule with a ``last_rule`` attribute (see :mod:`twin.decision`).
        """
        policy = self.policy
        k = policy.choose(decision)
        if k is None:
            return None, None
        if k < 0 or k >= len(decision.parts):
            raise IndexError(
                f"policy {type(policy).__name__} chose candidate {k} of "
                f"{len(decision.parts)} for robot {robot.index}"
            )
        rule = getattr(policy, "last_rule", None)
        self.recorder.decided(robot.index, rule or "?")
        return k, rule

    def noop(self, robot: Station) -> None:
        """A robot found no candidate and takes a NooP."""
        self.recorder.noop(robot.index)

    def down(self, robot: Station) -> None:
        """A robot broke down: under t_all the others must not wait for it."""
        self.waiting.pop(robot.index, None)
        self.expected.discard(robot.index)
        if self.scheme == "t_all":
            self._maybe_all()
        elif self.scheme == "t_any" and self.expected and self.expected <= set(self.waiting):
            robots = sorted(self.expected)
            self.expected = set()  # the epoch opens; the next free robot starts a new one
            self._open(robots)

    # -- epochs ------------------------------------------------------------------------------
    def _maybe_all(self) -> None:
        available = [r.index for r in self.robots if not r.down]
        if available and all(i in self.waiting for i in available):
            self._open(available)

    def _join_any(self, robot: Station) -> None:
        if not self.expected:
            self.expected = {robot.index}
            for other in self.robots:
                if other is not robot and other.interrupt_approach():
                    self.expected.add(other.index)
        else:
            self.expected.add(robot.index)
        if self.expected <= set(self.waiting):
            robots = sorted(self.expected)
            self.expected = set()
            self._open(robots)

    def _open(self, robots: list[int]) -> None:
        """The epoch opens: its robots no longer wait for one (in hold mode they are held
        until :meth:`release`, as if released now: a robot free at the same instant does
        not reopen it)."""
        self.epochs += 1
        if self.hold:
            for i in robots:
                self.held[i] = self.waiting.pop(i)
            self.pending.extend(robots)
            return
        for i in robots:  # in robot order, so upstream robots claim first
            self.waiting.pop(i).succeed()

    def release(self) -> list[int]:
        """Resume the robots of the pending epoch (hold mode); returns them."""
        robots, self.pending = sorted(self.pending), []
        for i in robots:  # in robot order, so upstream robots claim first
            self.held.pop(i).succeed()
        return robots
