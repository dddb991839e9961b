"""``capacity`` worded as a promise, with every crossing honest about how it ended; ``-r
auto``; a start flow that brings no part; runs (not flows) counted (issues #31, #32)."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.capacity import capacity_text, promise_gap, run_capacity
from pnp_twin.twin.loader import load_scenario

LINE = {"duration": 60.0, "warmup": 10.0, "seed": 3, "robots.count": 2}


def test_the_answer_is_a_promise_and_names_the_mean_and_upper_crossings() -> None:
    c = {
        "choice": {}, "robots": 6, "confidence": 0.95, "target": 95.0, "max_rate": 19.6,
        "ci_low": 16.4, "ci_high": 21.0, "policy": "SPT",
        "policies": {"max_rate": "SPT", "ci_low": "SPT", "ci_high": "SPT"},
        "search": {"max_rate": "found", "ci_low": "found", "ci_high": "found"},
    }  # fmt: skip
    text = capacity_text(c)
    assert text.startswith("With 6 robots running SPT you can promise 16.4 parts/s at G ≥ 95 %")
    assert "the mean crosses at 19.6 parts/s" in text
    assert "above 21 parts/s the line misses it with 95 % confidence" in text
    assert "surely" not in text and "sustains 19.6 parts/s [16.4, 21]" not in text
    assert "-r auto" not in text  # no replications said: nothing to suggest
    c["replications"] = 5  # the promise 16 % below the mean crossing: say what narrows it
    assert "5 replications per flow leave the promise 16 % below the mean crossing; -r auto" in (
        capacity_text(c)
    )


def test_an_undetermined_upper_crossing_is_said_so() -> None:
    c = {
        "choice": {}, "robots": 6, "confidence": 0.95, "target": 95.0, "max_rate": 19.6,
        "ci_low": 16.4, "ci_high": 40.0, "policy": "SPT",
        "policies": {"max_rate": "SPT", "ci_low": "SPT", "ci_high": "SPT"},
        "search": {"max_rate": "found", "ci_low": "found", "ci_high": "above"},
        "curve": [{"rate": 10.0}, {"rate": 40.0}],
    }  # fmt: skip
    text = capacity_text(c)
    assert "the upper bound still reaches it at the highest flow tried (40 parts/s)" in text
    assert "no flow was found where the line misses it" in text
    assert "above 40 parts/s the line misses it" not in text


def test_a_start_flow_that_brings_no_part_still_finds_the_capacity(tmp_path: Path) -> None:
    sc = load_scenario("paper_baseline", LINE)
    low = run_capacity(sc, tmp_path / "low", 90.0, 0.95, ["SD"], 4, 1, "simpy", start=0.001)
    usual = run_capacity(sc, tmp_path / "usual", 90.0, 0.95, ["SD"], 4, 1, "simpy")
    assert low["ci_low"] is not None and "no flow" not in low["text"], low["text"]
    assert low["ci_low"] <= low["max_rate"] <= low["ci_high"]  # never outside its interval
    assert abs(low["max_rate"] - usual["max_rate"]) <= 0.1 * usual["max_rate"]
    assert low["search"]["max_rate"] == "found"
    from pnp_twin.reports.capacity import build_capacity_report

    page = build_capacity_report(tmp_path / "usual").read_text()
    assert "surely" not in page and "above it: missed with 95 % confidence" in page
    assert "upper crosses" in page and "mean crosses" in page and "promise" in page


def test_replications_auto_doubles_until_the_promise_is_close_to_the_mean(
    tmp_path: Path,
) -> None:
    sc = load_scenario("paper_baseline", LINE)
    c = run_capacity(sc, tmp_path / "a", 90.0, 0.95, ["SD"], "auto", 1, "simpy", gap=0.04, most=20)
    auto = c["auto"]
    assert auto["replications"][0] == 5 and auto["replications"][-1] == c["replications"]
    assert auto["reached"] == promise_gap(c)
    assert auto["reached"] <= 0.04 or c["replications"] == 20
    assert len(auto["replications"]) > 1  # 5 replications leave the promise further off
    from pnp_twin.reports.capacity import build_capacity_report

    page = build_capacity_report(tmp_path / "a").read_text()
    assert "chosen by -r auto (" + " → ".join(map(str, auto["replications"])) in page
    # runs, not flows, are counted, and named so
    data = json.loads((tmp_path / "a" / "capacity.json").read_text())
    assert "simulated" not in data and data["runs_simulated"] >= c["flows_evaluated"] * 5


def test_cli_auto_and_a_bad_gap_is_one_line(tmp_path: Path) -> None:
    args = [
        "capacity",
        "paper_baseline",
        "--target",
        "90",
        "--set",
        "duration=60",
        "--set",
        "warmup=10",
    ]
    bad = CliRunner().invoke(app, [*args, "-r", "auto", "--gap", "2", "--out", str(tmp_path / "o")])
    assert bad.exit_code == 2 and "--gap: 2 is not allowed" in bad.stderr
    worse = CliRunner().invoke(app, [*args, "-r", "many", "--out", str(tmp_path / "o")])
    assert worse.exit_code == 2 and "give a whole number" in worse.stderr
    assert not (tmp_path / "o").exists()
