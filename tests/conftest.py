"""Shared helpers of the test-suite: small scenarios, a choice-logging policy, record checks.

Helpers are handed out as session-scoped fixtures (so hypothesis tests may use them too):

- ``make_scenario(overrides=None, **fields)`` builds a validated :class:`Scenario` from a
  small, fast default line through :func:`twin.loader.validate`. Dotted paths go in the
  ``overrides`` mapping (``{"robots.count": 2}``); keyword arguments use ``__`` for the dot
  (``robots__count=2``).
- ``logging_policy(inner)`` wraps a policy and logs every choice it makes.
- ``write_trace(path, rows)`` writes a feeder trace CSV of (time, y) rows.
- ``check_invariants(result, choices=None)`` asserts the invariants every run must keep
  (conservation of parts, workspaces, timing order, no overlapping robot states).
- ``foreign_signal_handlers``: SIGINT and SIGTERM handled by the test's own handler, to
  check that an in-process command gives them back.
- ``run_guarded(scenario, policy, seed=None)`` is :func:`twin.simulate` with a livelock
  guard: a run that keeps stepping at one simulated instant raises :class:`Livelock` (a
  TimeoutError) instead of hanging the test-suite.

Strict mode (``--strict-deps``, or the environment variable ``CI`` or ``PNP_TWIN_STRICT`` set
to anything but ``0``/``false``; ``.ci/run`` sets ``CI=1``): every skip is a failure. The
suite skips a test only when something it needs is missing (torch, safetensors, Ray, RLlib,
Stable-Baselines3, PettingZoo, playwright, Chromium, pdftotext, a shipped model), and the
``test`` extra and ``.ci/run`` install all of them, so in CI a skip means a broken install.

Every test must leave the SIGINT and SIGTERM handlers as it found them (a handler left
behind by an in-process command would swallow the signals meant for pytest): a test that
changes one fails, and the handler is put back.
"""

from __future__ import annotations

import csv
import os
import signal
from collections import Counter
from collections.abc import Callable, Generator, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

import pnp_twin.twin.run as twin_run
from pnp_twin.twin.decision import Decision, Policy, RobotSpec
from pnp_twin.twin.geometry import move_time
from pnp_twin.twin.line import Line
from pnp_twin.twin.loader import apply_overrides, validate
from pnp_twin.twin.run import RunResult
from pnp_twin.twin.scenario import Scenario

EPS = 1e-9
SAME_INSTANT_LIMIT = 20_000  # events at one simulated instant before a run is a livelock

# A four-robot line like paper_baseline, but short: 30 s of feeding, 5 s of warm-up.
BASE: dict[str, Any] = {
    "name": "test_line",
    "belt": {"length": 2.4, "width": 0.4, "speed": 0.8, "grid": [64, 8]},
    "feeder": {"arrival": "poisson", "rate": 10.0, "lateral": "normal", "lateral_sd": 0.08},
    "robots": {
        "count": 4,
        "first_workspace_start": 0.3,
        "workspace_length": 0.5,
        "workspace_gap": 0.0,
        "arm_speed": 3.0,
        "pick_time": 0.12,
        "place_time": 0.12,
        "bin_offset": [0.0, 0.25],
    },
    "policy": "SD",
    "termination": "t_continue",
    "duration": 30.0,
    "warmup": 5.0,
    "seed": 0,
}


def build_scenario(overrides: Mapping[str, Any] | None = None, **fields: Any) -> Scenario:
    """A validated scenario: BASE with dotted-path ``overrides`` and ``a__b=v`` fields."""
    changes = dict(overrides or {})
    changes.update({k.replace("__", "."): v for k, v in fields.items()})
    return validate(apply_overrides(BASE, changes))


class Livelock(TimeoutError):
    """The simulation kept processing events without simulated time advancing.

    A TimeoutError, so test modules can name it without importing conftest.
    """


class GuardedLine(Line):
    """A Line whose run stops with :class:`Livelock` instead of spinning at one instant.

    It processes exactly the events ``env.run(until=end_at)`` would, one step at a time.
    """

    def run(self) -> None:
        env, end = self.env, self.end_at
        last, same = -1.0, 0
        while env.peek() < end:
            env.step()
            if env.now == last:
                same += 1
                if same > SAME_INSTANT_LIMIT:
                    states = [(r.index, r.tool, r.claimed, r.down) for r in self.robots]
                    raise Livelock(
                        f"{same} events at t={env.now!r} without time advancing; "
                        f"robots (index, tool, claimed, down): {states}"
                    )
            else:
                last, same = env.now, 0
        env.run(until=end)


def run_guarded(scenario: Scenario, policy: Policy, seed: int | None = None) -> RunResult:
    """:func:`twin.simulate`, run on a :class:`GuardedLine`."""
    original = twin_run.Line
    twin_run.Line = GuardedLine  # type: ignore[misc]
    try:
        return twin_run.simulate(scenario, policy, seed=seed)
    finally:
        twin_run.Line = original  # type: ignore[misc]


@dataclass(frozen=True)
class Choice:
    """One answered decision, as the policy saw it."""

    robot: int
    time: float
    part: int
    intercept_time: float
    x: float
    y: float
    tool: tuple[float, float]
    candidates: tuple[int, ...]
    intercepts: tuple[float, ...]  # x of each candidate's interception point
    spec: RobotSpec


class LoggingPolicy:
    """A real policy (it delegates to ``inner``) that logs every decision it answers."""

    def __init__(self, inner: Policy) -> None:
        self.inner = inner
        self.name = getattr(inner, "name", type(inner).__name__)
        self.choices: list[Choice] = []

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.choices = []
        self.inner.reset(robots, rng)

    @property
    def last_rule(self) -> str | None:
        return getattr(self.inner, "last_rule", None)

    def choose(self, decision: Decision) -> int:
        k = self.inner.choose(decision)
        v = decision.spec.belt_speed
        self.choices.append(
            Choice(
                robot=decision.robot,
                time=decision.time,
                part=decision.parts[k],
                intercept_time=decision.times[k],
                x=decision.xs[k],
                y=decision.ys[k],
                tool=decision.tool,
                candidates=tuple(decision.parts),
                intercepts=tuple(
                    x + v * t for x, t in zip(decision.xs, decision.times, strict=True)
                ),
                spec=decision.spec,
            )
        )
        return k


def write_trace_file(path: Path, rows: Sequence[tuple[float, float]]) -> Path:
    """Write a feeder trace CSV (columns time, y) and return its path."""
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["time", "y"])
        for t, y in rows:
            w.writerow([repr(float(t)), repr(float(y))])
    return path


def robot_intervals(result: RunResult, robot: int) -> list[tuple[float, float, str]]:
    """Robot ``robot``'s (from 1, as the tables) busy cycles and noop/wait/down/interrupted spans.

    Blocked spans are left out: a box change blocks the robot inside a busy cycle.
    """
    parts, spans = result.parts, result.spans
    mine = parts[(parts["outcome"] == "picked") & (parts["robot"] == robot)]
    out = [
        (float(s), float(e), "busy")
        for s, e in zip(mine["decided_at"], mine["placed_at"], strict=True)
    ]
    other = spans[(spans["robot"] == robot) & (spans["state"] != "blocked")]
    out += [
        (float(s), float(e), str(k))
        for s, e, k in zip(other["start"], other["end"], other["state"], strict=True)
    ]
    return sorted(out)


def check_run(result: RunResult, choices: Sequence[Choice] | None = None) -> None:
    """Assert the invariants of one run (see the module docstring)."""
    sc = result.scenario
    parts, spans, kpis = result.parts, result.spans, result.kpis
    v = sc.belt.speed
    layout = sc.robots.layout()
    last_end = layout[-1][1]

    # every part fed in [0, duration) has exactly one row and one outcome
    assert parts["part"].is_unique
    assert ((parts["fed_at"] >= 0.0) & (parts["fed_at"] < sc.duration)).all()
    assert parts["fed_at"].is_monotonic_increasing
    assert set(parts["outcome"]) <= {"picked", "missed"}
    picked = parts[parts["outcome"] == "picked"]
    missed = parts[parts["outcome"] == "missed"]
    assert len(picked) + len(missed) == len(parts)
    assert picked["robot"].notna().all() and missed["robot"].isna().all()
    for col in ("decided_at", "picked_at", "placed_at"):
        assert np.isfinite(picked[col].to_numpy(dtype=float)).all(), col
        assert missed[col].isna().all(), col
    assert np.allclose(missed["left_at"], missed["fed_at"] + last_end / v, rtol=0, atol=EPS)

    # KPI counts agree with the records of the window
    win = parts[(parts["fed_at"] >= sc.warmup) & (parts["fed_at"] < sc.duration)]
    n_picked = int((win["outcome"] == "picked").sum())
    assert kpis["parts_presented"] == len(win)
    assert kpis["parts_picked"] == n_picked
    assert kpis["parts_missed"] == int((win["outcome"] == "missed").sum())
    assert kpis["parts_presented"] == kpis["parts_picked"] + kpis["parts_missed"]

    # picks happen inside the picking robot's workspace, in time order, with exact timing
    robot = picked["robot"].to_numpy(dtype=np.int64) - 1  # the tables number robots from 1
    xi = v * (picked["picked_at"].to_numpy() - picked["fed_at"].to_numpy())
    a = np.array([layout[r][0] for r in robot])
    b = np.array([layout[r][1] for r in robot])
    outside = (xi < a - EPS) | (xi > b + EPS)
    assert not outside.any(), picked[outside]
    dec, pick, place = (picked[c].to_numpy() for c in ("decided_at", "picked_at", "placed_at"))
    assert (pick >= dec).all()
    assert (place > pick).all()
    specs = {i: result_spec(result, i) for i in set(robot.tolist())}
    for (_, row), x in zip(picked.iterrows(), xi, strict=True):
        s = specs[int(row["robot"]) - 1]
        dist = float(np.hypot(s["bin"][0] - x, s["bin"][1] - row["y"]))
        expected = (
            row["picked_at"]
            + s["pick_time"]
            + move_time(dist, s["arm_speed"], s["acceleration"])
            + row["blocked_time"]
            + s["place_time"]
        )
        assert abs(row["placed_at"] - expected) < 1e-7, (row.to_dict(), expected)

    # a robot is in one state at a time: its cycles and spans never overlap
    assert (spans["end"] > spans["start"]).all()
    for r in range(sc.robots.count):
        iv = robot_intervals(result, r + 1)
        for (s0, e0, k0), (s1, e1, k1) in zip(iv, iv[1:], strict=False):
            assert s1 >= e0 - EPS, f"robot {r}: {k0} [{s0}, {e0}] overlaps {k1} [{s1}, {e1}]"

    if choices is not None:
        check_choices(result, choices)


def check_choices(result: RunResult, choices: Sequence[Choice]) -> None:
    """Each completed pick is one logged choice; no decision offers a part already taken."""
    picked = result.parts[result.parts["outcome"] == "picked"]
    done = {
        int(p): (int(r) - 1, float(d), float(t))  # 0-based, as Decision.robot
        for p, r, d, t in zip(
            picked["part"], picked["robot"], picked["decided_at"], picked["picked_at"], strict=True
        )
    }
    spans = result.spans
    cut = {
        (int(r) - 1, float(t))
        for r, t, k in zip(spans["robot"], spans["start"], spans["state"], strict=True)
        if k == "interrupted"
    }
    noop_at = {
        (int(r) - 1, float(t))
        for r, t, k in zip(spans["robot"], spans["start"], spans["state"], strict=True)
        if k == "noop"
    }
    per_instant = Counter((c.robot, c.time) for c in choices)
    matched = 0
    for c in choices:
        a, b = c.spec.workspace
        assert all(a - EPS <= x <= b + EPS for x in c.intercepts), c
        for p in c.candidates:  # a part claimed (for good) earlier is never offered again
            if p in done:
                assert not done[p][1] < c.time, (p, done[p], c)
        if done.get(c.part, (None,))[:2] == (c.robot, c.time):
            matched += 1
            assert done[c.part][2] == c.time + c.intercept_time  # picked_at = decided_at + T
            continue
        # a choice that did not end in a pick was cut short (t_any only): its robot has an
        # interrupted span from that instant, or (cut at once) decided again at that instant
        assert result.scenario.termination == "t_any", c
        key = (c.robot, c.time)
        assert key in cut or per_instant[key] > 1 or key in noop_at, c
    assert matched == len(done)  # each pick is exactly one choice: no part picked twice
    if result.scenario.termination != "t_any":
        assert not cut
        assert len(choices) == len(done)


def result_spec(result: RunResult, robot: int) -> dict[str, Any]:
    """Robot ``robot``'s (0-based) resolved parameters, computed from the scenario."""
    sc = result.scenario
    a, b = sc.robots.layout()[robot]
    dx, dy = sc.robot_param(robot + 1, "bin_offset")
    out = {
        n: float(sc.robot_param(robot + 1, n))
        for n in ("arm_speed", "acceleration", "pick_time", "place_time")
    }
    out["bin"] = ((a + b) / 2.0 + dx, sc.belt.width + dy)
    return out


def frames_equal(x: pd.DataFrame, y: pd.DataFrame) -> bool:
    """True when two record tables are identical, values and dtypes."""
    try:
        pd.testing.assert_frame_equal(x, y, check_exact=True)
    except AssertionError:
        return False
    return True


@pytest.fixture(scope="session")
def check_invariants() -> Callable[..., None]:
    """``check_invariants(result, choices=None)``: see :func:`check_run`."""
    return check_run


@pytest.fixture(scope="session")
def guarded() -> Callable[..., RunResult]:
    """``guarded(scenario, policy, seed=None)``: see :func:`run_guarded`."""
    return run_guarded


@pytest.fixture(scope="session")
def make_scenario() -> Callable[..., Scenario]:
    """``make_scenario(overrides=None, **fields)``: see :func:`build_scenario`."""
    return build_scenario


@pytest.fixture(scope="session")
def logging_policy() -> Callable[[Policy], LoggingPolicy]:
    """``logging_policy(inner)``: a policy that logs each choice of ``inner``."""
    return LoggingPolicy


@pytest.fixture(scope="session")
def write_trace() -> Callable[[Path, Sequence[tuple[float, float]]], Path]:
    """``write_trace(path, rows)``: write a trace CSV of (time, y) rows."""
    return write_trace_file


STRICT_ENV = ("CI", "PNP_TWIN_STRICT")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--strict-deps",
        action="store_true",
        default=False,
        help="fail every test that would be skipped (a missing dependency); implied by CI=1 "
        "or PNP_TWIN_STRICT=1",
    )


def strict_deps(config: pytest.Config) -> bool:
    """Whether skips are failures: ``--strict-deps``, or CI / PNP_TWIN_STRICT set and true."""
    if config.getoption("--strict-deps", default=False):
        return True
    for var in STRICT_ENV:
        value = os.environ.get(var, "").strip().lower()
        if value and value not in ("0", "false", "no", "off"):
            return True
    return False


def _skip_reason(report: pytest.CollectReport | pytest.TestReport) -> str:
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2])
    return str(longrepr)


def _fail_skip(config: pytest.Config, report: pytest.CollectReport | pytest.TestReport) -> None:
    if report.skipped and not hasattr(report, "wasxfail") and strict_deps(config):
        report.outcome = "failed"
        report.longrepr = (
            f"strict mode (--strict-deps, CI or PNP_TWIN_STRICT): a skip is a failure, "
            f"something the tests need is missing: {_skip_reason(report)}"
        )


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(
    collector: pytest.Collector,
) -> Generator[None, pytest.CollectReport, pytest.CollectReport]:
    report = yield
    _fail_skip(collector.config, report)
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    report = yield
    _fail_skip(item.config, report)
    return report


def _foreign_handler(signum: int, frame: Any) -> None:
    raise AssertionError(f"signal {signum} reached the test's own handler")


@pytest.fixture
def foreign_signal_handlers() -> Iterator[dict[int, Any]]:
    """SIGINT and SIGTERM handled by a handler of the test's own (neither the default nor
    Python's), as a program embedding ours would; the test checks they are still there after
    an in-process command. Put back afterwards."""
    handlers = {s: _foreign_handler for s in (signal.SIGINT, signal.SIGTERM)}
    before = {s: signal.signal(s, h) for s, h in handlers.items()}
    try:
        yield dict(handlers)
    finally:
        for s, h in before.items():
            signal.signal(s, h)


@pytest.fixture(autouse=True)
def _signal_handlers_restored() -> Iterator[None]:
    """Fail a test that leaves SIGINT or SIGTERM handled differently (and restore it)."""
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    changed = []
    for s, handler in before.items():
        now = signal.getsignal(s)
        if now is not handler:
            changed.append(f"{signal.Signals(s).name}: {handler!r} -> {now!r}")
            signal.signal(s, handler)
    assert not changed, f"the test left signal handlers changed: {'; '.join(changed)}"
