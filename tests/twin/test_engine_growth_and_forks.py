"""The fast engine grows its buffers and streams in place and its forks are independent.

Regression tests from the review of issue 12: a buffer that ran out used to restart the run
(asking a Python policy every decision again), a stream running out under a Python policy
was lost, and forks shared their rule codes and decision counts with the original."""

from __future__ import annotations

import numpy as np
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.fast import engine
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.loader import load_scenario


class _Warmup:
    """Names its first five choices "early", the rest "late": state kept across ``reset``
    (the Policy protocol: reset is "called once before a run")."""

    name = "warmup"

    def __init__(self) -> None:
        self.calls = 0
        self.last_rule: str | None = None

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        pass

    def choose(self, decision: Decision) -> int:
        self.calls += 1
        self.last_rule = "early" if self.calls <= 5 else "late"
        return 0


class _First:
    name = "first"
    last_rule = "FIFO"

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        pass

    def choose(self, decision: Decision) -> int:
        return 0


def test_a_span_buffer_restart_does_not_replay_a_python_policy(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Frequent short breakdowns and few parts overflow a small first span buffer guess; the
    buffer grows in place, so the Python policy is asked each decision once, as in SimPy."""
    sc = load_scenario(
        "breakdowns",
        {
            "termination": "t_continue",
            "duration": 20.0,
            "warmup": 0.0,
            "feeder.rate": 0.5,
            "robots.mtbf": 1.0,  # the lowest the scenario allows
            "robots.mttr": 0.01,
        },
    )
    rooms = FastLine._rooms
    monkeypatch.setattr(FastLine, "_rooms", lambda self: (16, *rooms(self)[1:]))
    a_policy, b_policy = _Warmup(), _Warmup()
    a = simulate(sc, a_policy, seed=3, engine="simpy")
    b = simulate(sc, b_policy, seed=3, engine="fast")
    assert b_policy.calls == a_policy.calls
    assert a.decisions.equals(b.decisions)


def test_a_stream_running_out_under_a_python_policy_is_grown_not_dropped(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A first guess of 3 breakdown draws per robot: the stream grows (drawing on from its
    generator) under a rule mix and under a Python policy alike, and matches SimPy."""
    sc = load_scenario(
        "breakdowns",
        {
            "termination": "t_continue",
            "duration": 60.0,
            "warmup": 0.0,
            "robots.mtbf": 2.0,
            "robots.mttr": 0.3,
        },
    )
    want = simulate(sc, _First(), seed=2, engine="simpy")
    rooms = FastLine._rooms
    monkeypatch.setattr(FastLine, "_rooms", lambda self: (*rooms(self)[:2], 3))
    mix = simulate(sc, make_policy("FIFO", 4), seed=2, engine="fast")
    got = simulate(sc, _First(), seed=2, engine="fast")
    down = lambda r: int((r.spans.state == "down").sum())  # noqa: E731
    assert down(mix) == down(want)  # the rule mix's path grows the stream: fine
    assert down(got) == down(want)  # 150 in SimPy (12 when the stream was lost)


def test_the_span_buffer_grows_in_place(monkeypatch: pytest.MonkeyPatch) -> None:
    """A first guess of 16 spans: advance grows the buffer in place (resized), never as a
    longer copy beside the old one (twice the memory at the peak: a reference to the buffer
    held across the kernel call did that), and the spans match a run with room enough."""
    copies: list[int] = []
    longer = engine._longer
    monkeypatch.setattr(engine, "_longer", lambda a, rows: copies.append(rows) or longer(a, rows))
    sc = load_scenario("paper_baseline", {"duration": 60.0, "warmup": 0.0})
    small, whole = FastLine(sc, rules=["SD"], seed=1), FastLine(sc, rules=["SD"], seed=1)
    small.start(16, *small._rooms()[1:])
    whole.start(*whole._rooms())
    assert small.advance(small.end_at) == whole.advance(whole.end_at) == L.ST_OK
    k = int(whole.gs[L.NSPANS])
    assert k > 16 and int(small.gs[L.NSPANS]) == k and len(small.sp_i) >= k
    assert copies == []
    np.testing.assert_array_equal(small.sp_i[:k], whole.sp_i[:k])
    np.testing.assert_array_equal(small.sp_f[:k], whole.sp_f[:k])


def _held(sc, epochs: int) -> FastLine:  # type: ignore[no-untyped-def]
    line = FastLine(sc, rules=["FIFO"], hold=True)
    line.start(*line._rooms())
    for _ in range(epochs):
        assert line.advance(line.end_at) == L.ST_EPOCH
        line.release()
    assert line.advance(line.end_at) == L.ST_EPOCH
    return line


def _finish(line: FastLine) -> None:
    line.release()
    while line.advance(line.end_at) == L.ST_EPOCH:
        line.release()


def test_a_fork_released_with_other_rules_leaves_the_original_alone() -> None:
    """``ip`` (the rule codes FastLine.release writes) is the fork's own: releasing the fork
    with SD leaves the original's rules and records alone."""
    sc = load_scenario("two_robot", {"duration": 30.0, "warmup": 1.0})
    line, ref = _held(sc, 20), _held(sc, 20)
    fork = line.fork()
    fork.release([L.SD] * len(fork.specs))
    np.testing.assert_array_equal(line.ip[:, L.RULE], ref.ip[:, L.RULE])
    _finish(line)
    _finish(ref)
    np.testing.assert_array_equal(line.rec_i, ref.rec_i)


def test_a_forks_python_choice_is_not_counted_in_the_original() -> None:
    """``extra_counts`` (the decisions table's counts of Python choices) is the fork's own."""
    sc = load_scenario("two_robot", {"duration": 10.0, "warmup": 1.0})
    line = FastLine(sc, _First(), seed=1)
    line.start(*line._rooms())
    assert line.advance(line.end_at) == L.ST_CHOOSE
    before = sum(line.extra_counts.values())
    fork = line.fork()
    fork.answer()
    assert sum(line.extra_counts.values()) == before
