"""Decision features of the lookahead's student: what the rules' picks and the robots look like.

The rollout-trained HDQN sees the belt image and the deciding robot's one-hot. The student
trained on the lookahead controller's values (:mod:`pnp_twin.learning.student`) sees a vector
of what the planner's choice turns on, all of it observable at the decision (``student-v1``,
computed here in Python; ``student-v2`` holds the same values and more, computed in one
compiled pass by :mod:`.features_compiled`):

- per rule (in the checkpoint's rule order): its pick's interception time from the tool, the
  time the pick has left in the deciding robot's workspace, its place across the belt, when
  the robot would be back at its bin after taking it (interception, grip, carry, place) and
  how many of the other candidates leave its workspace before then;
- per rule's pick also: the most time a downstream robot would have to spare for it (when it
  leaves that robot's workspace less when that robot is free; 0: no robot downstream gets
  it), and how many of the candidates the robot would lose meanwhile have no such slack;
- per robot: an estimate of the seconds until it is free (from the part it holds or gripped
  last, the belt's claims and grip times: grip, carry to its bin, place), the seconds since
  its last grip (a robot that is down stops gripping), its arm speed and the unclaimed parts
  in its workspace;
- the line: belt speed and the feeder's nominal rate (the scenario's, handed over by
  ``bind_run``; the parts fed so far per second when no scenario is bound) and the number of
  candidates;
- ``student-v2`` and ``student-v3``: per rule's pick, when the robot would have placed a
  second part after it and how many parts it could choose from then; the candidates one by
  one (place, across, interception time), which of them each rule picks, the nearest
  unclaimed parts upstream, and each robot's place along the line;
- ``student-v3`` and ``-v4``: per rule's pick, the line played on for a second over the
  parts already on the belt, every robot following SPT (:mod:`.continuation`): the parts
  gripped in it, by the robots downstream, by this robot after the pick, and how many fewer
  than the best pick's;
- ``student-v4`` only: the same four from the line played on until every part on the belt
  has passed the last workspace, counting each part's fate as the teacher does.

Every value is clipped to a small non-negative range (the numpy forward pass's bound needs
inputs >= 0). :data:`SETS` names the feature sets; a checkpoint records its set in ``meta.json``
(``features``), so the policy computes the same vector at inference.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Decision, RobotSpec

SETS = ("student-v1", "student-v2", "student-v3", "student-v4", "student-any-v1")
"""Known feature sets (``meta.json``'s ``features``); ``student-v2`` adds the deciding robot's
second pick and is computed by the compiled pass of :mod:`.features_compiled`; ``student-v3``
adds, per rule's pick, a second's continuation over the parts already on the belt;
``student-v4`` a continuation until those parts have left the line; ``student-any-v1`` is
``student-v4`` for any robot count and order (:mod:`.features_any`)."""
TAILS = {"student-v3": False, "student-v4": True, "student-any-v1": True}
ANY_COUNT = ("student-any-v1",)
"""The sets whose length and meaning do not depend on the robot count."""
"""The sets with a continuation tail, and whether it has the long continuation."""

HORIZON = 2.0
"""Times (interception, time left, busy) are clipped to [0, HORIZON] s."""
SINCE = 4.0
"""Seconds since a robot's last grip are clipped to [0, SINCE]."""
PER_PICK = 7
"""Features per rule's pick."""
PER_ROBOT = 4
"""Features per robot."""


def size(name: str, n_rules: int, n_robots: int) -> int:
    """Length of feature set ``name``'s vector (the robot one-hot included)."""
    check(name)
    if name in ANY_COUNT:
        from pnp_twin.policies.hdqn import features_any

        return features_any.size(n_rules)
    if name != "student-v1":
        from pnp_twin.policies.hdqn import continuation
        from pnp_twin.policies.hdqn import features_compiled as fc

        tail = continuation.size(n_rules, TAILS[name]) if name in TAILS else 0
        return fc.size(n_rules, n_robots) + tail
    return n_robots + PER_PICK * n_rules + PER_ROBOT * n_robots + 3


def check(name: str) -> None:
    if name not in SETS:
        raise ValueError(f"features: '{name}' is not a feature set; allowed {', '.join(SETS)}")


class DecisionFeatures:
    """Computes a feature set's vector for the decisions of one run."""

    def __init__(self, name: str, rules: Sequence[str]) -> None:
        check(name)
        self.name = name
        self.rules = list(rules)
        self.robots: list[RobotSpec] = []
        self.belt: Any = None
        self.rate: float | None = None
        self.rng = np.random.default_rng(0)
        self._table = np.zeros((0, 8))
        self._work = np.empty(0)  # the compiled pass's scratch, grown on demand
        self._pass: Any = None  # features_compiled, imported at reset (numba) for sets past v1
        self._tail: Any = None  # continuation, the v3 / v4 tail (None: a set without it)
        self._any: Any = None  # features_any, for a set of any robot count
        self._v4 = np.empty(0, np.float32)  # an any-count set's student-v4 vector
        self._params = np.zeros((0, 5))

    def reset(self, robots: list[RobotSpec], rate: float | None = None) -> None:
        """The run's robots and the feeder's nominal rate (None: measured from the belt)."""
        self.robots = list(robots)
        self.rate = rate
        if self.name != "student-v1":
            from pnp_twin.policies.hdqn import continuation, features_compiled

            self._pass = features_compiled
            self._tail = continuation if self.name in TAILS else None
            self._table = features_compiled.robot_table(self.robots)
        if self.name in ANY_COUNT:
            from pnp_twin.policies.hdqn import features_any

            self._any = features_any
            self._v4 = np.empty(size("student-v4", len(self.rules), len(self.robots)), np.float32)
            self._params = features_any.robot_params(self.robots)

    def attach(self, belt: Any) -> None:
        self.belt = belt

    def picks(self, decision: Decision) -> list[int]:
        """The part each rule would pick (rules here are deterministic; SIRO is not one)."""
        return [RULES[r](decision, self.rng) for r in self.rules]

    def vector(
        self, decision: Decision, picks: list[int] | None = None, out: np.ndarray | None = None
    ) -> np.ndarray:
        """The features of ``decision`` (float32, every entry >= 0); a compiled set writes
        them into ``out`` when given (a float32 array of the set's length)."""
        robots, n = self.robots, len(self.robots)
        spec = decision.spec
        now = decision.time
        if picks is None:
            picks = self.picks(decision)
        if self.name != "student-v1":
            return self._compiled(decision, picks, out)
        vals = [0.0] * size(self.name, len(self.rules), n)
        vals[decision.robot] = 1.0
        j = n
        b, v, w = spec.workspace[1], spec.belt_speed, spec.belt_width
        xs, ys, times = decision.xs, decision.ys, decision.times
        busy, since, load = self._robot_state(now)
        left = [(b - x) / v for x in xs]
        # the most time a downstream robot has to spare for each candidate: when it leaves
        # that robot's workspace, less when the robot is free (0: nobody downstream gets it)
        down = [r.workspace[1] for r in robots[decision.robot + 1 :]]
        free_at = busy[decision.robot + 1 :]
        slack = [
            max([(e - x) / v - f for e, f in zip(down, free_at, strict=True)], default=0.0)
            for x in xs
        ]
        bx, by = spec.bin
        arm, handling = spec.arm_speed, spec.pick_time + spec.place_time
        for k in picks:
            # back at the bin after picking k: its interception, grip, carry, place
            grip_x = xs[k] + v * times[k]
            back = times[k] + handling + math.hypot(bx - grip_x, by - ys[k]) / arm
            lost = [q for q, t in enumerate(left) if q != k and t < back]
            gone = sum(1 for q in lost if slack[q] <= 0.0)
            vals[j] = _clip(times[k], HORIZON)
            vals[j + 1] = _clip(left[k], HORIZON)
            vals[j + 2] = _clip(ys[k] / w, 1.0)
            vals[j + 3] = _clip(back, HORIZON)
            vals[j + 4] = min(len(lost), 5) / 5.0
            vals[j + 5] = _clip(slack[k], 2 * HORIZON) / 2.0
            vals[j + 6] = min(gone, 5) / 5.0
            j += PER_PICK
        for r in range(n):
            vals[j] = _clip(busy[r], HORIZON)
            vals[j + 1] = _clip(since[r], SINCE) / SINCE
            vals[j + 2] = robots[r].arm_speed / 4.0
            vals[j + 3] = min(load[r], 10) / 10.0
            j += PER_ROBOT
        vals[j] = spec.belt_speed
        vals[j + 1] = self._rate(now) / 10.0
        vals[j + 2] = len(decision.parts) / 10.0
        return np.asarray(vals, dtype=np.float32)

    def _compiled(self, decision: Decision, picks: list[int], out: np.ndarray | None) -> np.ndarray:
        fc = self._pass  # imported once, at reset, not per decision
        spec = decision.spec
        cand = np.array((decision.xs, decision.ys, decision.times), dtype=np.float64)
        line = np.array((spec.belt_speed, spec.belt_width, self._rate(decision.time)))
        belt = self._belt(decision.time)
        n, nb, nr = len(self.robots), belt.shape[1], len(self.rules)
        need = fc.work_size(n, cand.shape[1], nb)
        if self._tail is not None:  # the pass's busy times stay in work[:n] for the tail
            need = max(need, n + self._tail.work_size(n, nb, nr))
        if self._work.shape[0] < need:
            self._work = np.empty(2 * need)
        final = out
        if self._any is not None:  # student-v4 first, then pooled over the robots
            out = self._v4
        elif out is None:  # float32: each value rounds as astype would round it
            out = np.empty(size(self.name, nr, n), np.float32)
        picked = np.array(picks, np.int64)
        base = fc.size(nr, n)
        args = (decision.robot, decision.time, cand, picked, self._table, line, belt, self._work)
        fc.fill(out[:base], *args)
        if self._tail is not None:
            busy, work = self._work[:n], self._work[n:]
            self._tail.fill(out[base:], *args[:-1], busy, work, TAILS[self.name])
        if self._any is not None:
            if final is None:
                final = np.empty(size(self.name, nr, n), np.float32)
            per_robot = fc.PER_ROBOT
            slots = fc.slots_size(nr)
            self._any.pool(
                final, out, decision.robot, n, nr, fc.PER_PICK, per_robot, slots, self._params
            )
            return final
        return out

    def _belt(self, now: float) -> np.ndarray:
        """The on-belt parts' fed time, y, holder (-1: none) and grip time, as rows."""
        belt = self.belt
        if belt is None:
            return np.zeros((4, 0))
        on = belt.on_belt(now)
        lo, hi = on.start, on.stop
        return np.array(
            [belt.fed[lo:hi], belt.y[lo:hi], belt.holder[lo:hi], belt.left_at[lo:hi]],
            dtype=np.float64,
        ).reshape(4, hi - lo)

    def _rate(self, now: float) -> float:
        if self.rate is not None:
            return self.rate
        belt = self.belt
        if belt is None or now <= 0.0:
            return 0.0
        return float(belt.arrived) / now

    def _robot_state(self, now: float) -> tuple[list[float], list[float], list[int]]:
        """Per robot: seconds until free (0 if free or unknown), seconds since its last grip,
        and the unclaimed parts in its workspace now."""
        n = len(self.robots)
        busy = [0.0] * n
        since = [SINCE] * n
        load = [0] * n
        belt = self.belt
        if belt is None:
            return busy, since, load
        on = belt.on_belt(now)
        lo, hi = on.start, on.stop
        # plain floats: indexing numpy arrays (the compiled engine's belt) one by one is slow
        fed, ys = _floats(belt.fed, lo, hi), _floats(belt.y, lo, hi)
        holder, left_at = _floats(belt.holder, lo, hi), _floats(belt.left_at, lo, hi)
        v = belt.speed
        spaces = [r.workspace for r in self.robots]
        for i in range(hi - lo):
            r = int(holder[i])
            if r < 0:
                x = v * (now - fed[i])
                for q, (a, b) in enumerate(spaces):
                    if a <= x <= b:
                        load[q] += 1
                continue
            grip = left_at[i]
            if r >= n or grip == math.inf:
                continue
            spec = self.robots[r]
            x = v * (grip - fed[i])
            bx, by = spec.bin
            carry = math.hypot(bx - x, by - ys[i]) / spec.arm_speed
            free = grip + spec.pick_time + carry + spec.place_time
            if free - now > busy[r]:
                busy[r] = free - now
            if grip <= now and now - grip < since[r]:
                since[r] = now - grip
        return busy, since, load


def _clip(x: float, hi: float) -> float:
    return 0.0 if x < 0.0 else (hi if x > hi else x)


def _floats(a: Any, lo: int, hi: int) -> list[Any]:
    """``a[lo:hi]`` as a list of Python numbers (``a`` a list or a numpy array)."""
    part = a[lo:hi]
    return part.tolist() if isinstance(part, np.ndarray) else list(part)
