"""twin.robot: one robot, one part, on a hand-built line: candidates, the exact cycle times,
NooPs, an interrupted approach, breakdown draws.

The line: a 1 m belt at 0.5 m/s (4 x 2 cells: one belt tick is 0.5 s); one robot with
workspace [0.5, 1.0], base (0.75, 0.2), bin (0.75, 0.6), arm 1 m/s, grip 0.1 s, release
0.2 s; one part fed at t = 0 at y = 0.2. With v_b = 0.5 and v_r = 1 a part straight ahead
of the tool at distance d is met after d / 1.5 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import simpy

from pnp_twin.twin.belt import FREE, Belt
from pnp_twin.twin.bin import Bin
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.feeder import Feeder
from pnp_twin.twin.gateway import Gateway
from pnp_twin.twin.records import Recorder
from pnp_twin.twin.robot import Failures, Robot
from pnp_twin.twin.scenario import FeederConfig

SPEC = RobotSpec(0, 1, (0.5, 1.0), (0.75, 0.6), 1.0, 0.0, 0.1, 0.2, 0.5, 0.4)


class First:
    last_rule = "FIFO"

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        pass

    def choose(self, decision: Decision) -> int:
        return 0


def tiny_line(fed: list[float], ys: list[float]) -> tuple[simpy.Environment, Belt, Robot]:
    env = simpy.Environment()
    belt = Belt(1.0, 0.4, 0.5, (4, 2), end=1.0)
    belt.load(np.array(fed), np.array(ys))
    feeder = Feeder(FeederConfig(), 0.4, np.random.default_rng(0), np.random.default_rng(1))
    env.process(feeder.feeding(env, belt))
    rec = Recorder(len(fed))
    gw = Gateway(env, "t_continue", First(), rec)
    robot = Robot(env, SPEC, belt, Bin(env, SPEC.bin, 0, 0.0), rec)
    gw.robots = [robot]
    robot.start(gw)
    return env, belt, robot


def test_candidates_are_the_parts_met_inside_the_workspace():
    env, _belt, robot = tiny_line([0.0], [0.2])
    env.run(until=0.5)  # the part is at x = 0.25: met at x = 0.25 + 0.5 / 3, upstream of a
    assert robot.decision().parts == []
    env.run(until=1.0)  # at x = 0.5, 0.25 m ahead of the base: met after 1/6 s at x = 7/12
    d = robot.decision()
    assert d.parts == [0] and d.xs == [0.5] and d.ys == [0.2]
    assert d.times[0] == pytest.approx(1 / 6, abs=1e-15)


def test_one_cycle_has_the_hand_computed_times():
    env, belt, robot = tiny_line([0.0], [0.2])
    env.run(until=3.0)
    rec = robot.recorder
    grip = 1.0 + 1 / 6
    transfer = math.hypot(0.75 - 7 / 12, 0.6 - 0.2)  # 13/30 m at 1 m/s
    assert rec.decided_at == [1.0] and rec.robot == [0] and rec.rule == ["FIFO"]
    assert rec.picked_at[0] == pytest.approx(grip, abs=1e-12)
    assert rec.placed_at[0] == pytest.approx(grip + 0.1 + transfer + 0.2, abs=1e-12)
    assert rec.placed_at[0] == pytest.approx(1.9, abs=1e-12)
    assert belt.holder == [0] and belt.left_at[0] == pytest.approx(grip, abs=1e-12)
    assert robot.tool == SPEC.bin
    # NooPs of one belt tick while nothing comes: 0-0.5, 0.5-1, then from the place at 1.9
    noops = [(round(s, 9), round(e, 9)) for r, st, s, e in rec.spans if st == "noop"]
    assert noops == [(0.0, 0.5), (0.5, 1.0), (1.9, 2.4), (2.4, 2.9)]
    assert dict(rec.decisions) == {(0, "NooP"): 5, (0, "FIFO"): 1}


def test_interrupting_the_approach_releases_the_claim_and_stops_the_tool():
    env, belt, robot = tiny_line([0.0], [0.2])
    answers: list[bool] = []

    def interrupting() -> simpy.events.ProcessGenerator:
        yield env.timeout(0.2)
        answers.append(robot.interrupt_approach())  # in a NooP: nothing to interrupt
        yield env.timeout(1.1 - env.now)
        answers.append(robot.interrupt_approach())  # 0.1 s into the approach

    env.process(interrupting())
    env.run(until=3.0)
    assert answers == [False, True]
    spans = [(st, round(s, 9), round(e, 9)) for r, st, s, e in robot.recorder.spans]
    assert ("interrupted", 1.0, 1.1) in spans
    rec = robot.recorder
    assert rec.decided_at == [1.1]  # the second claim: from (0.65, 0.2), 0.1 m ahead
    assert rec.picked_at[0] == pytest.approx(1.1 + 0.1 / 1.5, abs=1e-12)


def test_a_released_part_is_free_again():
    env, belt, robot = tiny_line([0.0, 5.0], [0.2, 0.2])
    env.run(until=1.05)
    assert belt.holder[0] == 0 and robot.claimed == 0
    belt.release(0)
    assert belt.holder[0] == FREE and belt.left_at[0] == math.inf


def test_failures_draw_fixed_or_exponential_times():
    fixed = Failures(mtbf=50.0, mttr=5.0, distribution="fixed", rng=np.random.default_rng(0))
    assert fixed.draw(fixed.mtbf) == 50.0 and fixed.draw(fixed.mttr) == 5.0
    drawn = Failures(50.0, 5.0, "exponential", np.random.default_rng(3))
    assert drawn.draw(50.0) == float(np.random.default_rng(3).exponential(50.0))
