"""The line: a scenario turned into a SimPy model (belt, feeder, robots, bins, gateway).

Processes: the feeder puts parts on the belt (:meth:`Feeder.feeding`), the belt records the
parts it carries past the last workspace (:meth:`Belt.conveying`), each robot works its
cycle (:meth:`Robot.working`) and each bin changes full boxes (:meth:`Bin.changing_box`).
"""

from __future__ import annotations

import logging

import simpy

from pnp_twin.twin.belt import Belt
from pnp_twin.twin.bin import Bin
from pnp_twin.twin.decision import Policy
from pnp_twin.twin.feeder import Feeder, PartStream
from pnp_twin.twin.gateway import Gateway
from pnp_twin.twin.outfeed import Outfeed
from pnp_twin.twin.plan import (
    ARRIVALS,
    DRAIN_SLACK,
    FIRST_ROBOT,
    LATERAL,
    POLICY,
    LinePlan,
    overlap,
    robot_specs,
)
from pnp_twin.twin.records import Recorder
from pnp_twin.twin.robot import Failures, Robot
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

__all__ = ["DRAIN_SLACK", "Line", "robot_specs"]  # the last two now live in twin.plan


class Line:
    """One run of one scenario with one policy; ``streams`` are the run's random streams.

    Everything derived from the scenario (the seed split into independent child streams
    among them) is the run's :class:`~twin.plan.LinePlan`, which the fast engine reads too.
    ``parts`` replaces the feeder's own stream with a prepared one, e.g. a sampled future
    for rollouts (:func:`twin.feeder.resampled`); the rest of the run is unchanged.
    """

    def __init__(
        self,
        scenario: Scenario,
        policy: Policy,
        seed: int | None = None,
        hold: bool = False,
        duration: float | None = None,
        parts: PartStream | None = None,
    ) -> None:
        self.scenario = scenario
        self.plan = plan = LinePlan.of(scenario, seed, duration)
        self.seed = plan.seed
        self.duration = plan.duration
        streams = plan.streams()
        self.env = simpy.Environment()
        b = scenario.belt
        self.specs = plan.specs
        self.last_end = plan.last_end
        self.belt = Belt(b.length, b.width, b.speed, b.grid, end=self.last_end)
        arrivals, lateral = streams[ARRIVALS], streams[LATERAL]
        self.feeder = Feeder(
            scenario.feeder, b.width, arrivals, lateral, scenario.source_dir,
            streams[plan.kinds_stream],
        )  # fmt: skip
        if parts is None:
            parts = self.feeder.stream(self.duration)
        self.belt.load(*parts, plan.kind_codes(parts[2], len(parts[0])))
        self.recorder = Recorder(len(self.belt), outfeed=plan.outfeed is not None)
        self.outfeed = None if plan.outfeed is None else Outfeed(plan.outfeed)
        # the feeder first: at a shared instant it puts parts on the belt before robots look
        self.env.process(self.feeder.feeding(self.env, self.belt))
        self.env.process(self.belt.conveying(self.env, self.recorder))
        self.policy = policy
        policy.reset(self.specs, streams[POLICY])
        bind = getattr(policy, "bind_run", None)
        if callable(bind):  # policies that simulate the run themselves (lookahead) learn it
            bind(scenario, self.seed, self.duration)
        attach = getattr(policy, "attach", None)
        if callable(attach):  # policies that look at the belt (the learned one) get it here
            attach(self.belt)
        self.gateway = Gateway(self.env, scenario.termination, policy, self.recorder, hold)
        self.robots: list[Robot] = []
        for rp in plan.robots:
            spec = rp.spec
            failures = None
            if rp.breaks:
                rng = streams[FIRST_ROBOT + spec.index]
                failures = Failures(rp.mtbf, rp.mttr, rp.failures, rng)
            bins = [
                Bin(self.env, spec.bin, plan.capacity, plan.change_time) for _ in plan.kinds
            ]  # one bin (chute) per kind, at the robot's bin position
            robot = Robot(self.env, spec, self.belt, bins[0], self.recorder, failures, rp, bins)
            robot.outfeed = self.outfeed
            self.robots.append(robot)
        self.gateway.robots = self.robots
        if plan.rivals:  # facing robots: each knows the others whose x-range meets its own
            for robot in self.robots:
                robot.rivals = [
                    o for o in self.robots if o is not robot and overlap(o.spec, robot.spec)
                ]
        for robot in self.robots:
            robot.start(self.gateway)
        self.end_at = plan.end_at

    def run(self) -> None:
        """Feed for ``duration`` seconds, then drain until every part has an outcome."""
        log.debug("running %s seed %d until t=%.1f", self.scenario.name, self.seed, self.end_at)
        self.env.run(until=self.end_at)
        self.recorder.close_open_spans(self.now)  # a repair outlasting the run still counts

    @property
    def now(self) -> float:
        return float(self.env.now)
