"""The outfeed conveyor: containers of slots carried past the robots, placed into.

Positions are analytic, like the parts': container c enters at ``times[c]`` s (``c * gap``
for fixed spacing; drawn gaps, never shorter than a container, for Poisson or normal
arrivals) with its centre at ``x_in`` (co-flow: the upstream end of the robots' span, the
smallest a_i; counter-flow: its downstream end, the largest b_i) and moves at the signed
velocity ``u`` (+speed co-flow, -speed counter-flow), so slot k of container c is at
x = x_in + u (t - times[c]) + dx_k, y = y + dy_k. Nothing moves tick by tick.

:class:`OutfeedPlan` holds what follows from the scenario (derived once, in
:class:`twin.plan.LinePlan`); :class:`Outfeed` the run's state: which slots are taken
(reserved when a robot sets off, filled at the end of its place time).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.geometry import place_intercept
from pnp_twin.twin.scenario import OutfeedConfig


@dataclass(frozen=True)
class OutfeedPlan:
    """The outfeed of a line, as the run reads it (see the module docstring)."""

    u: float  # m/s, signed: +speed co-flow, -speed counter-flow
    gap: float  # s between containers entering
    x_in: float  # m: where a container's centre enters
    y: float  # m: the outfeed's centre line
    dx: tuple[float, ...]  # each slot's offset along x from the container's centre
    dy: tuple[float, ...]  # and across
    lo: tuple[tuple[float, ...], ...]  # [robot][slot]: where robot may place along x: lo..hi
    hi: tuple[tuple[float, ...], ...]  # (its x-range cut by its reach at the slot's y)
    entry: tuple[tuple[float, ...], ...]  # [robot][slot]: s after a container enters until
    # the slot enters the robot's place interval (inf: never)
    times: tuple[float, ...] = ()  # s: when each container enters, to past the run's end

    @classmethod
    def of(
        cls,
        config: OutfeedConfig,
        specs: Sequence[RobotSpec],
        until: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> OutfeedPlan:
        """The outfeed of a line whose run ends at ``until``; ``rng`` (the containers' own
        stream) draws the gaps of Poisson or normal arrivals."""
        u = config.sign * config.speed
        x_in = min(s.workspace[0] for s in specs) if u > 0 else max(s.workspace[1] for s in specs)
        dx = tuple(float(d[0]) for d in config.slots)
        dy = tuple(float(d[1]) for d in config.slots)
        los, his, entries = [], [], []
        for spec in specs:
            lo_r, hi_r, en_r = [], [], []
            for k in range(len(dx)):
                lo, hi = spec.workspace
                if spec.reach > 0.0:
                    mx, my = spec.mount
                    h2 = spec.reach * spec.reach - (config.y + dy[k] - my) ** 2
                    h = math.sqrt(h2) if h2 >= 0.0 else -math.inf
                    lo, hi = max(lo, mx - h), min(hi, mx + h)
                start = x_in + dx[k]  # where the slot appears
                if lo > hi or (u > 0 and start > hi) or (u < 0 and start < lo):
                    wait = math.inf  # never inside the robot's place interval
                elif u > 0:
                    wait = max(0.0, (lo - start) / u)
                else:
                    wait = max(0.0, (start - hi) / -u)
                lo_r.append(lo)
                hi_r.append(hi)
                en_r.append(wait)
            los.append(tuple(lo_r))
            his.append(tuple(hi_r))
            entries.append(tuple(en_r))
        waits = [w for row in entries for w in row if w < math.inf]
        times = arrivals(config, until + max(waits, default=0.0) + 2.0 * config.gap, rng)
        return cls(
            u, config.gap, x_in, config.y, dx, dy, tuple(los), tuple(his), tuple(entries),
            tuple(times.tolist()),
        )  # fmt: skip

    @property
    def n_slots(self) -> int:
        return len(self.dx)

    def entered_at(self, c: int) -> float:
        """When container c enters (its centre at x_in)."""
        return self.times[c]

    def slot_x(self, c: int, k: int, t: float) -> float:
        """x of slot k of container c at time t."""
        return self.x_in + self.u * (t - self.times[c]) + self.dx[k]

    def slot_y(self, k: int) -> float:
        return self.y + self.dy[k]

    def next_entry(self, robot: int, now: float) -> float:
        """The first instant after ``now`` at which a slot (of any container, free or not)
        enters robot ``robot``'s place interval: a holding robot's next try (inf: none)."""
        best = math.inf
        times = self.times
        for wait in self.entry[robot]:
            if wait == math.inf:
                continue
            c = bisect_right(times, now - wait)  # then exactly: the first entering after now
            while c > 0 and times[c - 1] + wait > now:
                c -= 1
            while c < len(times) and times[c] + wait <= now:
                c += 1
            if c < len(times) and times[c] + wait < best:
                best = times[c] + wait
        return best


def arrivals(config: OutfeedConfig, until: float, rng: np.random.Generator | None) -> np.ndarray:
    """When the containers enter, from 0 s to past ``until``: every ``gap`` s, or drawn gaps
    (Poisson, normal) each at least one container length long."""
    gap = config.gap
    if config.arrival == "fixed" or rng is None:
        return np.arange(int(math.floor(until / gap)) + 2) * gap  # c * gap, c = 0, 1, ...
    chunks, t = [np.zeros(1)], 0.0
    while t <= until:
        n = max(int((until - t) / gap * 1.2) + 16, 16)
        if config.arrival == "poisson":
            gaps = rng.standard_exponential(n) * gap
        else:
            gaps = rng.normal(gap, config.cv * gap, n)
        times = t + np.cumsum(np.maximum(gaps, config.min_gap))
        chunks.append(times)
        t = float(times[-1])
    return np.concatenate(chunks)


@dataclass(frozen=True)
class Slot:
    """A robot's place target: slot ``k`` of container ``c``, met after ``t`` s at (x, y)."""

    c: int
    k: int
    t: float
    x: float
    y: float


class Outfeed:
    """The run's outfeed: the plan and which slots are taken.

    A slot is reserved when a robot sets off towards it (:meth:`reserve`) and filled at the
    end of its place time; the filling time is recorded with the part
    (:meth:`twin.records.Recorder.slotted`), so no event of its own is needed."""

    def __init__(self, plan: OutfeedPlan) -> None:
        self.plan = plan
        self.taken: set[tuple[int, int]] = set()

    def reserve(self, slot: Slot) -> None:
        assert (slot.c, slot.k) not in self.taken, "a slot is reserved once"
        self.taken.add((slot.c, slot.k))

    def nearest(
        self,
        robot: int,
        spec: RobotSpec,
        tool: tuple[float, float],
        now: float,
        place_time: float,
    ) -> Slot | None:
        """The free slot robot ``robot`` intercepts soonest from ``tool`` at ``now`` (the
        first container, then the first slot, of equals), placing inside its place
        interval both when the release starts and when it ends ``place_time`` later; None
        when no free slot of an entered container is reachable."""
        p = self.plan
        u, times = p.u, p.times
        last = bisect_right(times, now) - 1  # the newest container that has entered
        best: Slot | None = None
        lo, hi = p.lo[robot], p.hi[robot]
        for c in range(last, -1, -1):  # newest first: older ones are further along
            gone = True
            for k in range(p.n_slots):
                x = p.x_in + u * (now - times[c]) + p.dx[k]
                if (u > 0 and x <= hi[k]) or (u < 0 and x >= lo[k]):
                    gone = False
                if (c, k) in self.taken or lo[k] > hi[k]:
                    continue
                y = p.y + p.dy[k]
                t = place_intercept(x - tool[0], y - tool[1], u, spec.arm_speed, spec.acceleration)
                xi = x + u * t
                xe = xi + u * place_time
                if not (lo[k] <= xi <= hi[k] and lo[k] <= xe <= hi[k]):
                    continue
                if best is None or t < best.t or (t == best.t and (c, k) < (best.c, best.k)):
                    best = Slot(c, k, t, xi, y)
            if gone:  # this container (and every older one) is past the robot
                break
        return best
