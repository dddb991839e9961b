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
    """One robot with workspace [a, b] over the full belt width and its own bin.

    The process :meth:`working` repeats: become free (the gateway may hold it), check for
    a due breakdown, look at the candidates, then either pick one (approach and grip, move
    to the bin and place) or take a NooP.
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
    ) -> None:
        """``plan``: the robot's derived constants as the line's plan computed them (computed
        here from ``spec`` when not given)."""
        self.env = env
        self.spec = spec
        self.index = spec.index
        self.belt = belt
        self.bin = bin_
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
        self.tool = self.base
        self.x_lo = plan.x_lo  # parts upstream of it cannot be met inside [a, b]
        self._quad = plan.quad
        self.failures = failures
        self.next_failure_at = math.inf
        if failures is not None:
            self.next_failure_at = failures.draw(failures.mtbf)
        self.down = False
        self.approach_until = -math.inf  # end of the current approach leg, for t_any
        self.claimed = -1
        self.gateway: Gateway | None = None
        self.process: simpy.Process | None = None

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

    def _candidates(self, now: float) -> tuple[list[int], list[float], list[float], list[float]]:
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

    # -- the cycle -------------------------------------------------------------------------
    def working(self) -> Generator[simpy.Event, Any, None]:
        env, rec, spec, gw = self.env, self.recorder, self.spec, self.gateway
        assert gw is not None
        belt, bin_, me = self.belt, self.bin, self.index
        v = belt.speed
        v_r, acc, pick = spec.arm_speed, spec.acceleration, spec.pick_time
        bx, by = bin_.position
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
            part, t = d.parts[k], d.times[k]
            tx, ty = d.xs[k] + v * t, d.ys[k]
            belt.claim(part, me, t0 + t)
            self.claimed = part
            self.approach_until = t0 + t
            try:
                yield timeout(t + pick)
            except simpy.Interrupt:
                belt.release(part)
                self.claimed = -1
                rec.span(me, "interrupted", t0, env.now)
                self.tool = position_along(self.tool, (tx, ty), env.now - t0, v_r, acc)
                continue
            self.claimed = -1
            rec.picked(part, me, rule, t0, t0 + t)
            dist = math.hypot(bx - tx, by - ty)
            arrive = env.now + (dist / v_r if acc <= 0.0 else move_time(dist, v_r, acc))
            blocked, done = bin_.place(arrive, spec.place_time)
            rec.placed(part, done, blocked)
            if blocked > 0.0:
                rec.span(me, "blocked", arrive, arrive + blocked)
            yield timeout(done - env.now)
            self.tool = bin_.position

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
