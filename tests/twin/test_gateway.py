"""twin.gateway: when robots decide (termination schemes, hold mode) and what is counted."""

from __future__ import annotations

import numpy as np
import pytest
import simpy

from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.gateway import Gateway
from pnp_twin.twin.records import Recorder


class FakeRobot:
    """A station as the gateway sees it; ``approaching`` says whether an interrupt lands."""

    def __init__(self, index: int, approaching: bool = False) -> None:
        self.index = index
        self.down = False
        self.approaching = approaching
        self.interrupted = 0

    def interrupt_approach(self) -> bool:
        if not self.approaching:
            return False
        self.approaching = False
        self.interrupted += 1
        return True


class Pick:
    """Answers every decision with candidate ``k``, naming ``rule`` (or no rule)."""

    def __init__(self, k: int, rule: str | None) -> None:
        self.k = k
        if rule is not None:
            self.last_rule = rule

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        pass

    def choose(self, decision: Decision) -> int:
        return self.k


SPEC = RobotSpec(0, 3, (0.3, 0.8), (0.55, 0.65), 3.0, 0.0, 0.12, 0.12, 0.8, 0.4)


def gateway(scheme: str, n: int = 3, hold: bool = False, policy: object = None) -> Gateway:
    env = simpy.Environment()
    gw = Gateway(env, scheme, policy or Pick(0, "SD"), Recorder(0), hold=hold)  # type: ignore[arg-type]
    gw.robots = [FakeRobot(i) for i in range(n)]
    return gw


def test_t_continue_decides_at_once_without_events():
    gw = gateway("t_continue")
    assert gw.decides_at_once and gw.free(gw.robots[1]) is None and gw.epochs == 0


def test_t_continue_in_hold_mode_pauses_for_the_driver():
    gw = gateway("t_continue", hold=True)
    assert not gw.decides_at_once
    event = gw.free(gw.robots[2])
    assert event is not None and not event.triggered
    assert gw.pending == [2] and gw.epochs == 1
    assert gw.release() == [2] and event.triggered and gw.pending == []


def test_t_all_waits_for_every_available_robot_then_releases_all():
    gw = gateway("t_all")
    r0, r1, r2 = gw.robots
    e0, e2 = gw.free(r0), gw.free(r2)
    assert e0 is not None and e2 is not None and not e0.triggered and not e2.triggered
    e1 = gw.free(r1)
    assert e1 is not None and e0.triggered and e1.triggered and e2.triggered
    assert gw.epochs == 1


def test_t_all_does_not_wait_for_a_robot_that_broke_down():
    gw = gateway("t_all")
    r0, r1, r2 = gw.robots
    e0, e1 = gw.free(r0), gw.free(r1)
    assert e0 is not None and e1 is not None and not e0.triggered
    r2.down = True
    gw.down(r2)
    assert e0.triggered and e1.triggered and gw.epochs == 1


def test_t_any_interrupts_approaching_robots_and_waits_for_them():
    gw = gateway("t_any")
    r0, r1, r2 = gw.robots
    r1.approaching = True  # r2 is placing a part: it is not interrupted, nor waited for
    e0 = gw.free(r0)
    assert e0 is not None and not e0.triggered
    assert (r1.interrupted, r2.interrupted) == (1, 0) and gw.expected == {0, 1}
    e1 = gw.free(r1)  # the interrupted robot reports free: the epoch opens for both
    assert e1 is not None and e0.triggered and e1.triggered and gw.expected == set()
    e2 = gw.free(r2)  # later: a new epoch, alone
    assert e2 is not None and e2.triggered and gw.epochs == 2


def test_t_any_epoch_completed_by_a_breakdown_leaves_no_stale_epoch():
    gw = gateway("t_any")
    r0, r1, r2 = gw.robots
    r1.approaching = True
    e0 = gw.free(r0)  # opens an epoch waiting for r0 and the interrupted r1
    assert e0 is not None and not e0.triggered and gw.expected == {0, 1}
    r1.down = True
    gw.down(r1)  # r1 breaks down instead of reporting: the epoch opens for r0 alone
    assert e0.triggered and gw.expected == set() and gw.epochs == 1
    e2 = gw.free(r2)  # later: r2 starts a new epoch of its own and decides at once
    assert e2 is not None and e2.triggered and gw.epochs == 2


def test_choose_returns_the_index_and_rule_and_counts_decisions():
    gw = gateway("t_continue", policy=Pick(1, "SPT"))
    d = Decision(SPEC, 0.0, (0.55, 0.2), [4, 7], [0.5, 0.4], [0.1, 0.3], [0.1, 0.2])
    assert gw.choose(gw.robots[0], d) == (1, "SPT")
    gw.noop(gw.robots[0])
    gw.noop(gw.robots[0])
    assert dict(gw.recorder.decisions) == {(0, "SPT"): 1, (0, "NooP"): 2}


def test_a_policy_without_a_rule_name_is_counted_as_question_mark():
    gw = gateway("t_continue", policy=Pick(0, None))
    d = Decision(SPEC, 0.0, (0.55, 0.2), [4], [0.5], [0.1], [0.1])
    assert gw.choose(gw.robots[2], d) == (0, None)
    assert dict(gw.recorder.decisions) == {(2, "?"): 1}


def test_an_answer_outside_the_candidates_is_refused():
    gw = gateway("t_continue", policy=Pick(2, "SD"))
    d = Decision(SPEC, 0.0, (0.55, 0.2), [4, 7], [0.5, 0.4], [0.1, 0.3], [0.1, 0.2])
    with pytest.raises(IndexError, match="chose candidate 2 of 2 for robot 0"):
        gw.choose(gw.robots[0], d)


def test_an_unknown_scheme_is_refused():
    with pytest.raises(ValueError, match="t_sometimes"):
        gateway("t_sometimes")
