"""The replay's reconstruction against the twin itself: at every decision the live line
hands its policy, the tool drawn is where the robot's tool is and each candidate part is
drawn where the belt has it; every shipped line shape; the window and its size."""

from __future__ import annotations

import json
from typing import Any

import pytest

from pnp_twin.policies import make_policy
from pnp_twin.reports.replay_data import parts_at, replay_data, tools_at
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate


class Watching:
    """A policy that answers as ``inner`` does and keeps what each decision saw."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.seen: list[tuple[int, float, tuple[float, float], list[int], list[float]]] = []

    def reset(self, robots: list[RobotSpec], rng: Any) -> None:
        self.inner.reset(robots, rng)

    def choose(self, d: Decision) -> int | None:
        self.seen.append((d.robot, d.time, d.tool, list(d.parts), list(d.xs)))
        return self.inner.choose(d)


SHAPES = [
    ("paper_baseline", {}),
    ("two_sided", {}),
    ("delta_over_belt", {}),
    ("waste_sorting", {}),
    ("tray_loading_coflow", {}),
    ("tray_loading_counterflow", {}),
    ("breakdowns", {}),
]


@pytest.mark.parametrize(("name", "sets"), SHAPES)
def test_tools_and_parts_drawn_where_the_twin_has_them(name: str, sets: dict) -> None:
    scn = load_scenario(name, {"duration": 40.0, "warmup": 10.0, **sets})
    watch = Watching(make_policy(scn.policy, scn.robots.count))
    result = simulate(scn, watch, seed=3)
    data = replay_data(
        result.parts, result.spans, scn.model_dump(mode="json"), seed=3, start=10.0, seconds=20
    )
    checked = 0
    for robot, t, tool, parts, xs in watch.seen:
        if not 10.0 <= t <= 30.0:
            continue
        drawn = tools_at(data, t)[robot]
        assert drawn == pytest.approx(tool, abs=2e-3), (robot, t)
        on_belt = parts_at(data, t)
        for part, x in zip(parts, xs, strict=True):
            assert on_belt[part][0] == pytest.approx(x, abs=2e-3)
        checked += 1
    assert checked > 20
    json.dumps(data)  # JSON-ready


def test_a_minute_of_paper_baseline_is_small() -> None:
    scn = load_scenario("paper_baseline")
    result = simulate(scn, make_policy("SD", scn.robots.count))
    data = replay_data(result.parts, result.spans, scn.model_dump(mode="json"), seconds=60)
    size = len(json.dumps(data, separators=(",", ":")))
    assert data["t0"] == 60.0 and data["t1"] == 120.0
    assert size < 400_000


def test_box_changes_are_marked_on_a_line_with_boxes() -> None:
    scn = load_scenario(
        "paper_baseline",
        {"duration": 60.0, "warmup": 0.0, "bins.capacity": 10, "bins.change_time": 4.0},
    )
    result = simulate(scn, make_policy("SD", scn.robots.count))
    data = replay_data(result.parts, result.spans, scn.model_dump(mode="json"))
    changes = [s for s in data["states"] if s[1] == 5]
    assert changes and all(b - a == pytest.approx(4.0, abs=1e-3) for _, _, a, b in changes)
