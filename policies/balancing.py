"""Line controllers' balancing modes (PickMaster / iRPickTool class) as policies.

Conveyor-tracking controllers do not run FIFO or SD across the line: the integrator sets a
*balancing mode* and the controller gives each part an owner when the camera detects it
upstream (at the feeder, here). A robot then picks only what it owns, in the order of a rule
(``rule=``, FIFO by default, as controllers pick in arrival order). The modes:

- ``share:40,30,30,100``: robot i owns at most its percentage of the parts that reach it; the
  rest are passed downstream (a part no robot takes is nobody's). Counted as a controller
  counts: robot i takes a part while its picks-to-be are below its share of the parts it has
  been offered (deterministic, no random draw).
- ``lane:0-0.1,0.1-0.2,0.2-0.3,0.3-0.4``: robot i owns the parts whose y lies in its band
  across the belt (m); a part on the boundary of two bands goes to the first robot listed.
  Together the bands cover the belt, each meeting the next (no gap, no overlap).
- ``list:1,2,3,4``: owners in a repeating sequence, part by part (robot numbers, 1 first).

A part its owner cannot reach (it leaves the owner's workspace unpicked) is lost, or with
``unreached=release`` released to every robot downstream of its owner, which then picks it
like any part it owns. A robot that owns no candidate takes a NooP (``choose`` returns
None). Settings follow the mode after ``;``: ``share:40,30,30,100;rule=SPT;unreached=release``.
The plain rules are the controllers' "no balancing" (greedy) mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pnp_twin.policies.rules import NAMED_RULES
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.errors import UserError, excerpt

MODES = ("share", "lane", "list")
UNREACHED = ("lost", "release")
NOBODY = -1


class BalancingError(UserError):
    """A malformed balancing mode or one that does not fit the line; one line."""


@dataclass(frozen=True)
class BalancingSettings:
    """One balancing mode as the integrator types it into the controller."""

    mode: str  # share, lane or list
    shares: tuple[float, ...] = ()  # share: % per robot
    lanes: tuple[tuple[float, float], ...] = ()  # lane: (lo, hi) in m per robot
    sequence: tuple[int, ...] = ()  # list: robot numbers (1 first)
    rule: str = "FIFO"  # the order within what a robot owns
    release: bool = False  # unreached=release: downstream robots may take it

    @property
    def name(self) -> str:
        """The canonical policy name."""
        if self.mode == "share":
            body = ",".join(f"{s:g}" for s in self.shares)
        elif self.mode == "lane":
            body = ",".join(f"{lo:g}-{hi:g}" for lo, hi in self.lanes)
        else:
            body = ",".join(str(r) for r in self.sequence)
        extra = f";rule={self.rule}" + (";unreached=release" if self.release else "")
        return f"{self.mode}:{body}{extra}"

    def controller_line(self) -> str:
        """What to type into the controller: 'robot 1: 38 %, robot 2: 33 %, ...'."""
        if self.mode == "share":
            return ", ".join(f"robot {i}: {s:g} %" for i, s in enumerate(self.shares, 1))
        if self.mode == "lane":
            return ", ".join(
                f"robot {i}: y {lo:g}-{hi:g} m" for i, (lo, hi) in enumerate(self.lanes, 1)
            )
        return "owners in turn: " + ", ".join(f"robot {r}" for r in self.sequence)


def parse(mode: str, arg: str) -> BalancingSettings:
    """Settings from ``mode`` and the text after ``mode:`` (one-line BalancingError)."""
    body, *extras = [p.strip() for p in arg.split(";")]
    where = f"policy: {mode}:{excerpt(arg)}"
    items = [x.strip() for x in body.split(",")] if body else []
    if not items or any(not x for x in items):
        raise BalancingError(f"{where}: give one value per robot, comma-separated ({_HELP[mode]})")
    kw: dict[str, object] = {"mode": mode}
    if mode == "share":
        kw["shares"] = tuple(_share(where, x) for x in items)
    elif mode == "lane":
        kw["lanes"] = tuple(_lane(where, x) for x in items)
    else:
        kw["sequence"] = tuple(_robot(where, x) for x in items)
    for extra in extras:
        key, sep, value = (p.strip() for p in extra.partition("="))
        if key == "rule" and sep and value.upper() in NAMED_RULES:
            kw["rule"] = value.upper()
        elif key == "unreached" and sep and value in UNREACHED:
            kw["release"] = value == "release"
        else:
            raise BalancingError(
                f"{where}: {excerpt(extra)} is not a setting; give rule=RULE "
                f"({', '.join(NAMED_RULES)}) or unreached=lost|release"
            )
    return BalancingSettings(**kw)  # type: ignore[arg-type]


_HELP = {
    "share": "a percentage 0..100 per robot, e.g. share:40,30,30,100",
    "lane": "a band lo-hi across the belt in m per robot, e.g. lane:0-0.2,0.2-0.4",
    "list": "robot numbers in turn, e.g. list:1,2,3,4",
}


def _number(where: str, text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise BalancingError(f"{where}: {excerpt(text)} is not a number ({what})")
    return value


def _share(where: str, text: str) -> float:
    value = _number(where, text, _HELP["share"])
    if not 0.0 <= value <= 100.0:
        raise BalancingError(f"{where}: share {text} is outside 0..100 (% of the parts)")
    return value


def _lane(where: str, text: str) -> tuple[float, float]:
    lo, sep, hi = text.partition("-")
    if not sep:
        raise BalancingError(f"{where}: lane {excerpt(text)} is not lo-hi ({_HELP['lane']})")
    a, b = _number(where, lo, _HELP["lane"]), _number(where, hi, _HELP["lane"])
    if not 0.0 <= a < b:
        raise BalancingError(f"{where}: lane {text} needs 0 <= lo < hi (m across the belt)")
    return a, b


def _robot(where: str, text: str) -> int:
    if not (text.isascii() and text.isdigit()) or int(text) < 1:
        raise BalancingError(f"{where}: {excerpt(text)} is not a robot number ({_HELP['list']})")
    return int(text)


def share_policy(arg: str) -> BalancingPolicy:
    """``share:40,30,30,100[;rule=R][;unreached=release]`` (the registry's factory)."""
    return BalancingPolicy(parse("share", arg))


def lane_policy(arg: str) -> BalancingPolicy:
    """``lane:0-0.2,0.2-0.4[;...]`` (the registry's factory)."""
    return BalancingPolicy(parse("lane", arg))


def list_policy(arg: str) -> BalancingPolicy:
    """``list:1,2,3,4[;...]`` (the registry's factory)."""
    return BalancingPolicy(parse("list", arg))


def check_fits(s: BalancingSettings, robots: list[RobotSpec]) -> None:
    """The mode fits the line: one value per robot, lanes covering the belt, known robots."""
    n, where = len(robots), f"policy: {s.name}"
    if s.mode == "share" and len(s.shares) != n:
        raise BalancingError(f"{where}: {len(s.shares)} shares for {n} robots; give one per robot")
    if s.mode == "lane":
        if len(s.lanes) != n:
            raise BalancingError(f"{where}: {len(s.lanes)} lanes for {n} robots; one per robot")
        width = robots[0].belt_width
        edge = 0.0
        for lo, hi in sorted(s.lanes):
            if lo > edge + 1e-9:
                raise BalancingError(
                    f"{where}: the lanes leave a gap from y = {edge:g} to {lo:g} m; together "
                    f"they cover the belt (0..{width:g} m), each meeting the next"
                )
            if lo < edge - 1e-9:
                raise BalancingError(
                    f"{where}: lane {lo:g}-{hi:g} m overlaps the lane below it (up to {edge:g} "
                    "m); lanes meet at their boundaries (a part on one goes to the first listed)"
                )
            edge = hi
        if abs(edge - width) > 1e-9:
            raise BalancingError(
                f"{where}: the lanes end at y = {edge:g} m; together they cover the belt "
                f"(0..{width:g} m)"
            )
    if s.mode == "list" and max(s.sequence) > n:
        raise BalancingError(f"{where}: robot {max(s.sequence)} is not a robot; allowed 1..{n}")


class BalancingPolicy:
    """A balancing mode with a rule for the order within what each robot owns."""

    def __init__(self, settings: BalancingSettings) -> None:
        self.settings = settings
        self.name = settings.name
        self.robots: list[RobotSpec] = []
        self.rng = np.random.default_rng(0)
        self.last_rule: str | None = None
        self.owner: list[int] = []  # list, share: part index -> owner (NOBODY), feed order
        self._offered: list[int] = []  # share: parts offered to each robot so far
        self._taken: list[int] = []  # share: parts it took

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        check_fits(self.settings, robots)
        self.robots, self.rng = list(robots), rng
        self.owner, self.last_rule = [], None
        self._offered, self._taken = [0] * len(robots), [0] * len(robots)

    def choose(self, decision: Decision) -> int | None:
        """The rule's pick among the candidates this robot owns (or may take: released);
        None when it owns none (it takes a NooP)."""
        mine = [k for k in range(len(decision)) if self._may_take(decision, k)]
        if not mine:
            self.last_rule = None
            return None
        sub = Decision(
            decision.spec,
            decision.time,
            decision.tool,
            [decision.parts[k] for k in mine],
            [decision.xs[k] for k in mine],
            [decision.ys[k] for k in mine],
            [decision.times[k] for k in mine],
            [decision.kinds[k] for k in mine],
        )
        self.last_rule = self.settings.rule
        return mine[NAMED_RULES[self.settings.rule](sub, self.rng)]

    def _may_take(self, d: Decision, k: int) -> bool:
        owner = self.owner_of(d.parts[k], d.ys[k])
        if owner == d.robot:
            return True
        if not self.settings.release or owner == NOBODY:
            return False
        return d.xs[k] > self.robots[owner].workspace[1]  # it left its owner's workspace

    def owner_of(self, part: int, y: float) -> int:
        """The owner the controller gave ``part`` when it was detected: by its y (lane), or
        counted in feed order (list, share: every part fed before it is assigned first)."""
        s = self.settings
        if s.mode == "lane":
            return next((i for i, (lo, hi) in enumerate(s.lanes) if lo <= y <= hi), NOBODY)
        while len(self.owner) <= part:
            p = len(self.owner)
            if s.mode == "list":
                self.owner.append(s.sequence[p % len(s.sequence)] - 1)
            else:
                self.owner.append(self._share_owner())
        return self.owner[part]

    def _share_owner(self) -> int:
        """share: the first robot, upstream first, still below its share of the parts
        offered to it takes the part; the others were offered it too."""
        for i, share in enumerate(self.settings.shares):
            self._offered[i] += 1
            if self._taken[i] < share / 100.0 * self._offered[i] - 1e-9:
                self._taken[i] += 1
                return i
        return NOBODY
