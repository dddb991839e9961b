"""A robot: its workspace, its tool, and the pick-and-place cycle as a SimPy process."""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import simpy

from pnp_twin.twin.belt import FREE, Belt
from pnp_twin.twin.bin import Bin
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.geometry import (
    intercept_now,
    intercept_quad,
    intercept_time,
    move_time,
    position_along,
)
from pnp_twin.twin.outfeed import Outfeed
from pnp_twin.twin.plan import RobotPlan, reach_margin
from pnp_twin.twin.records import Recorder

if TYPE_CHECKING:
    from pnp_twin.twin.gateway import Gateway


@dataclass(frozen=True)
class Failures:
    """One robot's breakdowns: mean time between failures and to repair (s), their
    distribution ("exponential" or "fixed") and the robot's own random stream."""

    mtbf: float
    mttr: float
    distribution: str
    rng: np.random.Generator

    def draw(self, mean: float) -> float:
        """A time between failures or to repair with mean ``mean``."""
        if self.distribution == "fixed":
            return mean
        return float(self.rng.exponential(mean))


class Robot:
    """One robot with workspace [a, b] over the full belt width and its own bin (one per
    kind of part: a chute each, at the same position).

    The process :meth:`working` repeats: become free (the gateway may hold it), check for
    a due breakdown, look at the candidates, then either pick one (approach and grip, move
    to the bin and place) or take a NooP.

    A candidate is an unclaimed part of a kind the robot picks whose interception point lies
    in [a, b] and, with a reach, within ``reach`` of the robot's base. Where robots face each
    other (their x-ranges overlap), a part that several *idle* robots (not approaching a part
    claimed before this instant, not carrying, not down) could take is a candidate only of
    the one that intercepts it soonest, an exact tie going to the robot first in the run's
    random priority order: so who takes a contested part does not depend on how the robots
    are numbered or in which order robots free at the same instant decide.
    """

    def __init__(
        self,
        env: simpy.Environment,
        spec: RobotSpec,
        belt: Belt,
        bin_: Bin,
        recorder: Recorder,
        failures: Failures | None = None,
        plan: RobotPlan | None = None,
        bins: list[Bin] | None = None,
    ) -> None:
        """``plan``: the robot's derived constants as the line's plan computed them (computed
        here from ``spec`` when not given); ``bins``: one per kind code (``[bin_]`` when not
        given)."""
        self.env = env
        self.spec = spec
        self.index = spec.index
        self.belt = belt
        self.bin = bin_
        self.bins = bins or [bin_]
        self.recorder = recorder
        self.a, self.b = spec.workspace
        if plan is None:
            plan = RobotPlan(
                spec,
                reach_margin(spec),
                intercept_quad(spec.arm_speed, spec.belt_speed),
                ((self.a + self.b) / 2.0, belt.width / 2.0),
                0.0,
                0.0,
                "",
            )
        self.base = plan.base
        self.priority = plan.priority
        self.tool = self.base
        self.busy = False  # approaching, gripping or carrying a part (not idle)
        self.rivals: list[Robot] = []  # robots whose x-range overlaps this one's (the line)
        # candidates pass more tests than the x-range (kinds, reach, rivals): the full loop
        # (and a line of several kinds: the full loop reports each candidate's kind)
        self.filtered = spec.reach > 0 or bool(spec.picks)
        self.x_lo = plan.x_lo  # parts upstream of it cannot be met inside [a, b]
        self._quad = plan.quad
        self.failures = failures
        self.next_failure_at = math.inf
        if failures is not None:
            self.next_failure_at = failures.draw(failures.mtbf)
        self.down = False
        self.approach_until = -math.inf  # end of the current approach leg, for t_any
        self.claimed = -1
        self.claimed_at = -math.inf  # decision time of the current claim
        self.gateway: Gateway | None = None
        self.process: simpy.Process | None = None
        self.outfeed: Outfeed | None = None  # set by the line: place onto it, not the bin

    def start(self, gateway: Gateway) -> None:
        """Start the robot's process, reporting to ``gateway``."""
        self.gateway = gateway
        self.process = self.env.process(self.working())

    def interrupt_approach(self) -> bool:
        """Stop the approach leg now (t_any) if the robot is on one: its claim is released
        and the tool stops where it is. False when it is not approaching a part."""
        if self.claimed < 0 or self.approach_until <= self.env.now:
            return False
        assert self.process is not None
        self.process.interrupt("t_any")
        return True

    # -- candidates -------------------------------------------------------------------------
    def decision(self) -> Decision:
        """The candidates now: unclaimed parts whose interception point lies in [a, b]."""
        return Decision(self.spec, self.env.now, self.tool, *self._candidates(self.env.now))

    def _candidates(self, now: float) -> tuple[list[Any], ...]:
        """(parts, xs, ys, times[, kinds]): the kinds only where the full loop ran."""
        if self.filtered or self.rivals:
            return self._filtered_candidates(now)
        belt = self.belt
        v = belt.speed
        fed, ys_all, holder = belt.fed, belt.y, belt.holder
        px, py = self.tool
        a, b, quad = self.a, self.b, self._quad
        acc = self.spec.acceleration
        closed_form = intercept_now  # a local name: this loop is the twin's hot path
        vnow = v * now
        parts: list[int] = []
        xs: list[float] = []
        ys: list[float] = []
        times: list[float] = []
        for i in belt.span(now, self.x_lo, b):
            if holder[i] != FREE:
                continue
            x = vnow - v * fed[i]
            y = ys_all[i]
            dx = x - px
            dy = y - py
            if acc > 0.0:
                t = intercept_time(dx, dy, v, self.spec.arm_speed, acc)
            else:
                t = closed_form(dx, dy, v, quad)
            if a <= x + v * t <= b:
                parts.append(i)
                xs.append(x)
                ys.append(y)
                times.append(t)
        return parts, xs, ys, times

    def intercept(self, x: float, y: float) -> float:
        """Interception time of a part now at (x, y) from the tool, with this arm."""
        dx, dy = x - self.tool[0], y - self.tool[1]
        spec = self.spec
        if spec.acceleration > 0.0:
            return intercept_time(dx, dy, spec.belt_speed, spec.arm_speed, spec.acceleration)
        return intercept_now(dx, dy, spec.belt_speed, self._quad)

    def picks(self, kind: int) -> bool:
        """Whether this robot picks parts of kind code ``kind``."""
        return not self.spec.picks or self.spec.picks[kind]

    def can_take(self, x: float, y: float, t: float) -> bool:
        """Whether a part now at (x, y), intercepted after ``t`` s, may be this robot's: met
        inside [a, b] and within its reach (its kind is asked first: :meth:`picks`)."""
        spec = self.spec
        xi = x + spec.belt_speed * t
        if not self.a <= xi <= self.b:
            return False
        if spec.reach > 0.0:
            mx, my = spec.mount
            return (xi - mx) * (xi - mx) + (y - my) * (y - my) <= spec.reach * spec.reach
        return True

    def _yields_to(self, kind: int, x: float, y: float, t: float) -> bool:
        """Whether an idle rival would intercept this part sooner (or as soon, and comes
        first in the priority order): then it is the rival's, not a candidate here.

        A rival that claimed a part at this very instant still counts as idle (its tool has
        not moved): so robots free at one instant see the same rivals whatever order they
        decide in."""
        now = self.env.now
        for other in self.rivals:
            if other.down or (other.busy and (other.claimed < 0 or other.claimed_at < now)):
                continue
            if not other.picks(kind):
                continue
            t_other = other.intercept(x, y)
            if not other.can_take(x, y, t_other):
                continue
            if t_other < t or (t_other == t and other.priority < self.priority):
                return True
        return False

    def _filtered_candidates(self, now: float) -> tuple[list[Any], ...]:
        """:meth:`_candidates` with every test (kinds, reach, rivals): the readable loop."""
        belt = self.belt
        v = belt.speed
        parts: list[int] = []
        xs: list[float] = []
        ys: list[float] = []
        times: list[float] = []
        kinds: list[int] = []
        for i in belt.span(now, self.x_lo, self.b):
            if belt.holder[i] != FREE:
                continue
            kind = belt.kind_code[i]
            if not self.picks(kind):
                continue
            x, y = v * now - v * belt.fed[i], belt.y[i]
            t = self.intercept(x, y)
            if not self.can_take(x, y, t):
                continue
            if self.rivals and self._yields_to(kind, x, y, t):
                continue
            parts.append(i)
            xs.append(x)
            ys.append(y)
            times.append(t)
            kinds.append(kind)
        return parts, xs, ys, times, kinds

    # -- the cycle -------------------------------------------------------------------------
    def working(self) -> Generator[simpy.Event, Any, None]:
        env, rec, spec, gw = self.env, self.recorder, self.spec, self.gateway
        assert gw is not None
        belt, me = self.belt, self.index
        v = belt.speed
        v_r, acc = spec.arm_speed, spec.acceleration
        bx, by = self.bin.position  # every kind's chute is at the robot's bin position
        timeout = env.timeout
        decides_at_once = gw.decides_at_once
        while True:
            if env.now >= self.next_failure_at:
                yield from self._breaking_down()
            hold = None if decides_at_once else gw.free(self)
            if hold is not None:
                t0 = env.now
                rec.begin(me, "wait", t0)
                yield hold
                rec.span(me, "wait", t0, env.now)
            t0 = env.now
            found = self._candidates(t0)
            if not found[0]:
                yield from self._noop()
                continue
            d = Decision(spec, t0, self.tool, *found)
            k, rule = gw.choose(self, d)
            if k is None:  # the policy picks nothing now
                yield from self._noop()
                continue
            part, t, kind = d.parts[k], d.times[k], d.kinds[k]
            tx, ty = d.xs[k] + v * t, d.ys[k]
            belt.claim(part, me, t0 + t)
            self.claimed = part
            self.claimed_at = t0
            self.busy = True
            self.approach_until = t0 + t
            try:
                yield timeout(t + spec.pick_of(kind))
            except simpy.Interrupt:
                belt.release(part)
                self.claimed = -1
                self.busy = False
                rec.span(me, "interrupted", t0, env.now)
                self.tool = position_along(self.tool, (tx, ty), env.now - t0, v_r, acc)
                continue
            self.claimed = -1
            rec.picked(part, me, rule, t0, t0 + t)
            if self.outfeed is not None:
                yield from self._placing(self.outfeed, part, spec.place_of(kind), (tx, ty))
                continue
            dist = math.hypot(bx - tx, by - ty)
            arrive = env.now + (dist / v_r if acc <= 0.0 else move_time(dist, v_r, acc))
            blocked, done = self.bins[kind].place(arrive, spec.place_of(kind))
            rec.placed(part, done, blocked)
            if blocked > 0.0:
                rec.span(me, "blocked", arrive, arrive + blocked)
            yield timeout(done - env.now)
            self.tool = self.bin.position
            self.busy = False

    def _placing(
        self, outfeed: Outfeed, part: int, place: float, grip: tuple[float, float]
    ) -> Generator[simpy.Event, Any, None]:
        """The place leg onto the outfeed: to the free slot met soonest (reserved now,
        filled ``place`` s after the tool meets it, the tool moving with it meanwhile). With
        no free slot in reach the robot holds the part at the grip point until the next
        slot enters its place interval (:meth:`OutfeedPlan.next_entry`), then tries again."""
        env, rec, me = self.env, self.recorder, self.index
        self.tool = grip
        held_from = -math.inf
        while True:
            slot = outfeed.nearest(me, self.spec, grip, env.now, place)
            if slot is not None:
                break
            if held_from == -math.inf:
                held_from = env.now
                rec.begin(me, "holding", held_from)
                rec.held(part, held_from)
            wake = outfeed.plan.next_entry(me, env.now)
            if wake == math.inf:  # no slot will ever come: hold to the end of the run
                yield env.event()
            yield env.timeout(wake - env.now)
        if held_from > -math.inf:
            rec.span(me, "holding", held_from, env.now)
        outfeed.reserve(slot)
        done = env.now + slot.t + place
        rec.placed(part, done, 0.0)
        rec.slotted(part, slot.c, slot.k, env.now - held_from if held_from > -math.inf else 0.0)
        yield env.timeout(done - env.now)
        self.tool = (slot.x + outfeed.plan.u * place, slot.y)
        self.busy = False

    def _noop(self) -> Generator[simpy.Event, Any, None]:
        """Wait until the next part enters the workspace or one belt tick, if sooner."""
        env = self.env
        assert self.gateway is not None
        self.gateway.noop(self)
        wait = min(self.belt.next_entry(env.now, self.a), self.belt.tick)
        if env.now + wait <= env.now:  # too small to move the clock: a NooP must let time pass
            wait = self.belt.tick
        t0 = env.now
        yield env.timeout(wait)
        self.recorder.span(self.index, "noop", t0, env.now)

    def _breaking_down(self) -> Generator[simpy.Event, Any, None]:
        """A due failure takes effect at the next decision point (no part is in the tool)."""
        assert self.failures is not None and self.gateway is not None
        env = self.env
        self.down = True
        self.gateway.down(self)
        t0 = env.now
        self.recorder.begin(self.index, "down", t0)
        yield env.timeout(self.failures.draw(self.failures.mttr))
        self.recorder.span(self.index, "down", t0, env.now)
        self.down = False
        self.next_failure_at = env.now + self.failures.draw(self.failures.mtbf)
