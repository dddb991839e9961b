"""A robot: its workspace, its tool, and the pick-and-place cycle as a SimPy process."""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import TYPE_CHECKING, Any

import numpy as np
import simpy

from twin.belt import FREE, Belt
from twin.bin import Bin
from twin.decision import Decision, RobotSpec
from twin.geometry import intercept_time, move_time, position_along
from twin.records import Recorder

if TYPE_CHECKING:
    from twin.gateway import Gateway


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
        failures: tuple[float, float, str, np.random.Generator] | None = None,
    ) -> None:
        self.env = env
        self.spec = spec
        self.index = spec.index
        self.belt = belt
        self.bin = bin_
        self.recorder = recorder
        self.a, self.b = spec.workspace
        self.base = ((self.a + self.b) / 2.0, belt.width / 2.0)
        self.tool = self.base
        # Upstream parts can only be intercepted inside [a, b] when the tool is far from
        # them; beyond this margin the tool always meets them before x = a.
        xs = (self.a, self.b, spec.bin[0])
        ys = (0.0, belt.width, spec.bin[1])
        reach = math.hypot(max(xs) - min(xs), max(ys) - min(ys))
        self.x_lo = self.a - reach * spec.belt_speed / spec.arm_speed
        self._quad = spec.arm_speed**2 - spec.belt_speed**2
        self.failures = failures
        self.next_failure_at = math.inf
        if failures is not None:
            self.next_failure_at = self._draw(failures[0])
        self.down = False
        self.approach_until = -math.inf  # end of the current approach leg, for t_any
        self.claimed = -1
        self.gateway: Gateway | None = None
        self.process: simpy.Process | None = None

    def start(self, gateway: Gateway) -> None:
        self.gateway = gateway
        self.process = self.env.process(self.working())

    # -- candidates -------------------------------------------------------------------------
    def decision(self) -> Decision:
        """The candidates now: unclaimed parts whose interception point lies in [a, b]."""
        now = self.env.now
        belt = self.belt
        v = belt.speed
        fed, ys_all, holder = belt.fed, belt.y, belt.holder
        px, py = self.tool
        a, b, quad = self.a, self.b, self._quad
        acc = self.spec.acceleration
        parts: list[int] = []
        xs: list[float] = []
        ys: list[float] = []
        times: list[float] = []
        for i in belt.span(now, self.x_lo, b):
            if holder[i] != FREE:
                continue
            x = v * (now - fed[i])
            y = ys_all[i]
            dx = x - px
            dy = y - py
            if acc > 0.0:
                t = intercept_time(dx, dy, v, self.spec.arm_speed, acc)
            else:
                t = (dx * v + math.sqrt(dx * dx * v * v + quad * (dx * dx + dy * dy))) / quad
            xi = x + v * t
            if a <= xi <= b:
                parts.append(i)
                xs.append(x)
                ys.append(y)
                times.append(t)
        return Decision(self.spec, now, self.tool, parts, xs, ys, times)

    # -- the cycle -------------------------------------------------------------------------
    def working(self) -> Generator[simpy.Event, Any, None]:
        env, rec, spec, gw = self.env, self.recorder, self.spec, self.gateway
        assert gw is not None
        belt, bin_, me = self.belt, self.bin, self.index
        v = belt.speed
        while True:
            if env.now >= self.next_failure_at:
                yield from self._breaking_down()
            hold = gw.free(self)
            if hold is not None:
                t0 = env.now
                yield hold
                rec.span(me, "wait", t0, env.now)
            d = self.decision()
            if not d.parts:
                yield from self._noop()
                continue
            k = gw.choose(self, d)
            part, t = d.parts[k], d.times[k]
            t0 = env.now
            target = (d.xs[k] + v * t, d.ys[k])
            belt.holder[part] = me
            belt.left_at[part] = t0 + t
            self.claimed = part
            self.approach_until = t0 + t
            try:
                yield env.timeout(t + spec.pick_time)
            except simpy.Interrupt:
                belt.holder[part] = FREE
                belt.left_at[part] = math.inf
                self.claimed = -1
                rec.span(me, "interrupted", t0, env.now)
                self.tool = position_along(
                    self.tool, target, env.now - t0, spec.arm_speed, spec.acceleration
                )
                continue
            self.claimed = -1
            rec.robot[part] = me
            rec.rule[part] = d.rule
            rec.decided_at[part] = t0
            rec.picked_at[part] = t0 + t
            dist = math.hypot(bin_.position[0] - target[0], bin_.position[1] - target[1])
            arrive = env.now + move_time(dist, spec.arm_speed, spec.acceleration)
            blocked, done = bin_.place(arrive, spec.place_time)
            rec.blocked[part] = blocked
            rec.placed_at[part] = done
            if blocked > 0.0:
                rec.span(me, "blocked", arrive, arrive + blocked)
            yield env.timeout(done - env.now)
            self.tool = bin_.position

    def _noop(self) -> Generator[simpy.Event, Any, None]:
        """Wait until the next part enters the workspace or one belt tick, if sooner."""
        env = self.env
        assert self.gateway is not None
        self.gateway.noop(self)
        wait = min(self.belt.next_entry(env.now, self.a), self.belt.tick)
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
        yield env.timeout(self._draw(self.failures[1]))
        self.recorder.span(self.index, "down", t0, env.now)
        self.down = False
        self.next_failure_at = env.now + self._draw(self.failures[0])

    def _draw(self, mean: float) -> float:
        assert self.failures is not None
        if self.failures[2] == "fixed":
            return mean
        return float(self.failures[3].exponential(mean))
