"""``design`` and ``capacity``: bounds that keep a question finite, checked before the
folder exists (one ``error:`` line, exit code 2, nothing written)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app

CASES = [
    (["capacity", "two_robot", "--target", "90", "--start", "0"], "--start: 0 parts/s"),
    (
        ["design", "trace_replay", "--target", "60", "--vary", "robots.count=2:3",
         "--set", "belt.length=3"],
        "one replayed trace is one sample",
    ),
    (["capacity", "two_robot", "--target", "90", "--start", "nan"], "--start: nan"),
    (["capacity", "two_robot", "--target", "50", "-r", "100000000"], "give 2 to 1000"),
    (["capacity", "two_robot", "--target", "50", "-p", "FOO"], "'FOO' is not a rule"),
    (
        ["design", "two_robot", "--target", "50", "--vary", "robots.count=1:2", "-p", "FOO"],
        "'FOO' is not a rule",
    ),
    (
        ["design", "two_robot", "--target", "50", "--vary", "robots.count=1:2",
         "--max-replications", "100000000"],
        "max-replications <= 1000",
    ),
    (
        ["design", "two_robot", "--target", "50", "--vary", "robots.count=1:2",
         "--vary", "robots.count=2:2"],
        "given twice",
    ),
    (
        ["capacity", "two_robot", "--target", "50", "--vary", "robots.count=1:2",
         "--vary", "robots.count=2:2"],
        "given twice",
    ),
    (
        ["design", "two_robot", "--target", "50", "--vary", "robots.count=1:30",
         "--vary", "robots.arm_speed=" + ",".join(str(1 + i / 10) for i in range(40)),
         "--vary", "belt.speed=" + ",".join(str(0.2 + i / 100) for i in range(20))],
        "configurations to try",
    ),
]  # fmt: skip


@pytest.mark.parametrize(("args", "message"), CASES, ids=[m for _, m in CASES])
def test_unbounded_questions_are_refused_before_the_folder(
    tmp_path: Path, args: list[str], message: str
) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(app, [*args, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert result.output.count("error:") == 1 and message in result.output
    assert not out.exists()


def test_capacity_stops_at_the_highest_flow_a_scenario_allows(tmp_path: Path) -> None:
    """A line that grips any flow is answered "above" at 1000 parts/s, not with an error
    about the flow's bound."""
    args = ["capacity", "two_robot", "--target", "0.5", "-r", "2", "--engine", "simpy"]
    args += ["--set", "duration=4", "--set", "warmup=1", "--json", "--out", str(tmp_path / "c")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["search"]["ci_high"] == "above" and data["ci_high"] == 1000.0
