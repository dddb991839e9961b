"""``pnp-twin capacity``: the highest part flow at a target, by root finding over common
random numbers, checked against brute force on a made-up line; asking again reuses runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.capacity import run_capacity
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario, with_overrides

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "feeder.rate": 3.0, "duration": 80.0, "warmup": 10.0, "seed": 4}


@pytest.fixture(scope="module")
def found(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    folder = tmp_path_factory.mktemp("capacity") / "cap"
    sc = load_scenario(BASELINE, overrides=LINE)
    return folder, run_capacity(sc, folder, 80.0, 0.95, ["SD"], 4, 1, "simpy")


def test_the_promised_flow_meets_the_target_with_other_seeds(found: tuple[Path, dict]) -> None:
    folder, c = found
    assert c["search"] == {"max_rate": "found", "ci_low": "found", "ci_high": "found"}
    assert c["ci_low"] <= c["max_rate"] <= c["ci_high"]
    # brute force, independent seeds: at the promised flow the line meets the target, and
    # well past the upper crossing it misses it
    sc = load_scenario(BASELINE, overrides=LINE)
    ev = Evaluator(folder / "check", ["SD"], replication_seeds(sc.seed + 99, 6), [], 1, "simpy")
    at = {
        rate: ev.predict([with_overrides(sc, {"feeder.rate": rate})], [str(rate)])[0]
        for rate in (c["ci_low"], 1.5 * c["ci_high"])
    }
    assert at[c["ci_low"]].mean["gripping_rate"] >= 80.0
    assert at[1.5 * c["ci_high"]].mean["gripping_rate"] < 80.0
    # the curve is every evaluated flow; fewer than a grid fine enough for 1 %
    assert len(c["curve"]) == c["evaluated"] < 40


def test_asking_again_reuses_the_stored_flows(found: tuple[Path, dict]) -> None:
    folder, first = found
    sc = load_scenario(BASELINE, overrides=LINE)
    again = run_capacity(sc, folder, 80.0, 0.9, ["SD"], 4, 1, "simpy")
    assert again["simulated"] < again["evaluated"] and again["replayed"] > 0
    assert again["ci_low"] >= first["ci_low"]  # a lower confidence promises more, not less
    assert json.loads((folder / "capacity.json").read_text())["confidence"] == 0.9


def test_cli_json_and_a_trace_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "cap"
    args = ["capacity", str(BASELINE), "--target", "70", "--out", str(out), "-r", "2"]
    sets = ["robots.count=2", "duration=30", "warmup=5", "feeder.rate=3", "seed=2"]
    for s in sets:
        args += ["--set", s]
    result = CliRunner().invoke(app, [*args, "--workers", "1", "--engine", "simpy", "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert {"max_rate", "ci_low", "ci_high", "text"} <= set(data)
    assert (out / "report.html").is_file() and "capacity" in (out / "report.html").read_text()
    sc = load_scenario("trace_replay", {"duration": 30.0})
    with pytest.raises(StudyError, match="a replayed trace fixes the part flow"):
        run_capacity(sc, tmp_path / "t", 80.0)
