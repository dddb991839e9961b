"""The line: a scenario turned into a SimPy model (belt, feeder, robots, bins, gateway).

Processes: the feeder puts parts on the belt (:meth:`Feeder.feeding`), the belt records the
parts it carries past the last workspace (:meth:`Belt.conveying`), each robot works its
cycle (:meth:`Robot.working`) and each bin changes full boxes (:meth:`Bin.changing_box`).
"""

from __future__ import annotations

import logging

import numpy as np
import simpy

from pnp_twin.twin.belt import Belt
from pnp_twin.twin.bin import Bin
from pnp_twin.twin.decision import Policy, RobotSpec
from pnp_twin.twin.feeder import Feeder, PartStream
from pnp_twin.twin.gateway import Gateway
from pnp_twin.twin.geometry import bin_position
from pnp_twin.twin.records import Recorder
from pnp_twin.twin.robot import Failures, Robot
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

DRAIN_SLACK = 30.0  # s after the last part passed the last workspace, for the last places


def robot_specs(scenario: Scenario) -> list[RobotSpec]:
    """Each robot's resolved parameters (shared defaults with per-robot overrides)."""
    out = []
    belt = scenario.belt
    for i, (a, b) in enumerate(scenario.robots.layout()):
        p = lambda name, i=i: scenario.robot_param(i + 1, name)  # noqa: E731
        out.append(
            RobotSpec(
                index=i,
                count=scenario.robots.count,
                workspace=(a, b),
                bin=bin_position((a, b), belt.width, p("bin_offset")),
                arm_speed=float(p("arm_speed")),
                acceleration=float(p("acceleration")),
                pick_time=float(p("pick_time")),
                place_time=float(p("place_time")),
                belt_speed=belt.speed,
                belt_width=belt.width,
            )
        )
    return out


class Line:
    """One run of one scenario with one policy; ``streams`` are the run's random streams.

    The seed is split into independent child streams (feeder arrivals, lateral positions,
    policy, one per robot for breakdowns), so the part stream does not depend on the policy.
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
        self.seed = scenario.seed if seed is None else seed
        self.duration = scenario.duration if duration is None else duration
        n = scenario.robots.count
        streams = [np.random.default_rng(s) for s in np.random.SeedSequence(self.seed).spawn(3 + n)]
        self.env = simpy.Environment()
        b = scenario.belt
        self.specs = robot_specs(scenario)
        self.last_end = self.specs[-1].workspace[1]
        self.belt = Belt(b.length, b.width, b.speed, b.grid, end=self.last_end)
        self.feeder = Feeder(scenario.feeder, b.width, streams[0], streams[1], scenario.source_dir)
        if parts is None:
            parts = self.feeder.stream(self.duration)
        self.belt.load(*parts)
        self.recorder = Recorder(len(self.belt))
        # the feeder first: at a shared instant it puts parts on the belt before robots look
        self.env.process(self.feeder.feeding(self.env, self.belt))
        self.env.process(self.belt.conveying(self.env, self.recorder))
        self.policy = policy
        policy.reset(self.specs, streams[2])
        attach = getattr(policy, "attach", None)
        if callable(attach):  # policies that look at the belt (the learned one) get it here
            attach(self.belt)
        self.gateway = Gateway(self.env, scenario.termination, policy, self.recorder, hold)
        self.robots: list[Robot] = []
        for spec in self.specs:
            i = spec.index + 1
            mtbf, mttr = scenario.robot_param(i, "mtbf"), scenario.robot_param(i, "mttr")
            failures = None
            if mtbf > 0:
                dist = scenario.robots.failure_distribution
                failures = Failures(mtbf, mttr, dist, streams[3 + spec.index])
            bin_ = Bin(self.env, spec.bin, scenario.bins.capacity, scenario.bins.change_time)
            robot = Robot(self.env, spec, self.belt, bin_, self.recorder, failures)
            self.robots.append(robot)
        self.gateway.robots = self.robots
        for robot in self.robots:
            robot.start(self.gateway)
        change = scenario.bins.change_time
        self.end_at = self.duration + self.last_end / b.speed + DRAIN_SLACK + change

    def run(self) -> None:
        """Feed for ``duration`` seconds, then drain until every part has an outcome."""
        log.debug("running %s seed %d until t=%.1f", self.scenario.name, self.seed, self.end_at)
        self.env.run(until=self.end_at)
        self.recorder.close_open_spans(self.now)  # a repair outlasting the run still counts

    @property
    def now(self) -> float:
        return float(self.env.now)
