"""Continuations from a forked decision (twin.fast.rollouts) are the SimPy twin's replays.

The rollout labels replay each what-if from t = 0 on a spliced part stream; the fast engine
forks the run at the decision instead. Both must give the same records, also when a NooP
under way at the decision was timed by a part the sampled future redraws.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.fast.rollouts import continue_each, continue_one
from pnp_twin.twin.feeder import Feeder, splice
from pnp_twin.twin.line import Line
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.scenario import Scenario


class _Recorded:
    """SPT, remembering each choice; replays ``prefix`` then ``forced`` when given."""

    name = "recorded"

    def __init__(self, prefix: list[int] | None = None, forced: int | None = None) -> None:
        self.prefix, self.forced, self.chosen = prefix or [], forced, []

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.rng = rng

    def choose(self, d: Decision) -> int:
        j = len(self.chosen)
        if j < len(self.prefix):
            k = self.prefix[j]
        elif j == len(self.prefix) and self.forced is not None:
            k = self.forced
        else:
            k = RULES["SPT"](d, self.rng)
        self.chosen.append(k)
        return k


def _decisions(sc: Scenario, seed: int, until: float):
    """Each decision of an SPT episode before ``until``: (fork, prefix, candidates)."""
    policy = _Recorded()
    line = FastLine(sc, policy, seed=seed)
    line.start(*line._rooms())
    while line.advance(until) == L.ST_CHOOSE:
        fork = line.fork()
        prefix = list(policy.chosen)
        line.answer()
        yield fork, prefix, int(fork.gs[L.DN])


def _replay(sc: Scenario, seed: int, future, prefix: list[int], k: int, stop: float):
    run = Line(sc, _Recorded(prefix, k), seed=seed, parts=future)
    run.env.run(until=stop)
    rec = run.recorder
    return np.asarray(rec.decided_at), np.asarray(rec.picked_at), np.asarray(rec.robot)


def _retimed(fork: FastLine, fed: np.ndarray, n_kept: int) -> int:
    """NooPs under way whose end the sampled future moves (the replay times them anew)."""
    ist, fs, tick = fork.ist, fork.fs, fork.gp[L.TICK]
    moved = 0
    for q in range(len(ist)):
        if ist[q, L.ACTIVE] and ist[q, L.PC] == L.PC_NOOP and ist[q, L.NOOPPART] >= n_kept:
            now = fs[q, L.T0]
            wait = min(tick, fed[n_kept] + fork.fp[q, L.BA] / fork.gp[L.V] - now)
            moved += bool(now + wait != fs[q, L.WAKE])
    return moved


@pytest.mark.parametrize("start", [0.0, 0.3])
def test_continuations_equal_replays_from_the_start(start: float) -> None:
    """With the first workspace at the feeder (start 0) NooPs are timed by the next part's
    entry, often one the future redraws; the continuation retimes them as the replay does."""
    sc = load_scenario(
        "paper_baseline",
        {
            "duration": 12.0,
            "warmup": 0.0,
            "feeder.rate": 10.0,
            "robots.first_workspace_start": start,
        },
    )
    seed, retimed, checked = 3, 0, 0
    own = Feeder.seeded(sc, seed).stream(sc.duration)
    for j, (fork, prefix, n) in enumerate(_decisions(sc, seed, 8.0)):
        t = fork.now
        if t < 2.0:
            continue
        n_kept = int(np.searchsorted(fork.fed, t, "right"))
        future = splice(own, Feeder.seeded(sc, 1000 + j).stream(sc.duration), t)
        retimed += _retimed(fork, future[0], n_kept)
        stop = t + 3.0
        for k in range(n):
            rec_i, rec_f = continue_one(fork, future[:2], n_kept, k, "SPT", stop)
            decided, picked, robot = _replay(sc, seed, future, prefix, k, stop)
            np.testing.assert_array_equal(rec_f[:, 0], decided)
            np.testing.assert_array_equal(rec_f[:, 1], picked)
            np.testing.assert_array_equal(rec_i[:, 0], robot)
            checked += 1
    assert checked > 20
    if start == 0.0:
        assert retimed > 0  # some NooP under way ends at another time in the future


def test_continue_each_sums_the_window_over_futures() -> None:
    sc = load_scenario("paper_baseline", {"duration": 10.0, "warmup": 0.0})
    own = Feeder.seeded(sc, 1).stream(sc.duration)
    fork, prefix, n = next((f, p, n) for f, p, n in _decisions(sc, 1, 8.0) if f.now > 3.0)
    t = fork.now
    n_kept = int(np.searchsorted(fork.fed, t, "right"))
    futures = [splice(own, Feeder.seeded(sc, m).stream(sc.duration), t) for m in (5, 6)]
    lo, hi, stop = t - 1.0, t + 2.0, t + 3.5
    streams = [f[:2] for f in futures]
    totals = continue_each(fork, streams, n_kept, list(range(n)), "SPT", stop, (lo, hi))
    assert totals is not None and len(totals) == n
    for k in range(n):
        want = 0
        for f in futures:
            _, picked, _ = _replay(sc, 1, f, prefix, k, stop)
            fed = f[0]
            want += int(((fed >= lo) & (fed < hi) & ~np.isnan(picked)).sum())
        assert totals[k] == want
    with pytest.raises(ValueError, match="not stopped at a decision"):
        done = FastLine(sc, rules=["SPT"])
        done.run()
        continue_each(done, streams, n_kept, [0], "SPT", stop, (lo, hi))


@st.composite
def _lines(draw: st.DrawFn) -> tuple[Scenario, int]:
    data: dict[str, Any] = {
        "duration": 10.0,
        "warmup": 0.0,
        "termination": draw(st.sampled_from(["t_continue", "t_all", "t_any"])),
        "feeder.rate": draw(st.floats(2.0, 16.0)),
        "robots.count": draw(st.integers(1, 4)),
        "robots.first_workspace_start": draw(st.sampled_from([0.0, 0.02, 0.3])),
        "robots.acceleration": draw(st.sampled_from([0.0, 10.0])),
        "bins.capacity": draw(st.sampled_from([0, 3])),
        "bins.change_time": 1.0,
    }
    if draw(st.booleans()):
        data.update({"robots.mtbf": draw(st.floats(2.0, 10.0)), "robots.mttr": 1.0})
    return load_scenario("paper_baseline", data), draw(st.integers(0, 2**20))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_lines())
def test_random_continuations_equal_replays(case: tuple[Scenario, int]) -> None:
    sc, seed = case
    own = Feeder.seeded(sc, seed).stream(sc.duration)
    for j, (fork, prefix, n) in enumerate(_decisions(sc, seed, 6.0)):
        if j % 7:  # every seventh decision, all its candidates
            continue
        t = fork.now
        n_kept = int(np.searchsorted(fork.fed, t, "right"))
        future = splice(own, Feeder.seeded(sc, seed + 1 + j).stream(sc.duration), t)
        for k in range(n):
            rec_i, rec_f = continue_one(fork, future[:2], n_kept, k, "SPT", t + 2.5)
            decided, picked, robot = _replay(sc, seed, future, prefix, k, t + 2.5)
            np.testing.assert_array_equal(rec_f[:, 0], decided)
            np.testing.assert_array_equal(rec_f[:, 1], picked)
            np.testing.assert_array_equal(rec_i[:, 0], robot)
