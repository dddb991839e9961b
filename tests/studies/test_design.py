"""``pnp-twin design``: the cheapest configuration meeting a target with a confidence that
holds after the selection, checked against brute force with other seeds on a made-up line;
the sequential procedure runs fewer replications than a fixed count; asking again reuses."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.design import parse_vary, read_costs, run_design
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.stats import t_interval

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {
    "robots.count": 2,
    "feeder.rate": 4.0,
    "duration": 60.0,
    "warmup": 10.0,
    "seed": 5,
    "belt.length": 3.0,
}
COSTS = """
belt_price = 5000
lost_part_cost = 0.02
hours = 2000
[robot_price]
"2.0" = 20000
"4.0" = 26000
"""
VARY = ["robots.count=1:5", "robots.arm_speed=2.0,4.0"]


@pytest.fixture(scope="module")
def designed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    root = tmp_path_factory.mktemp("design")
    (root / "costs.toml").write_text(COSTS)
    sc = load_scenario(BASELINE, overrides=LINE)
    d = run_design(
        sc, root / "d", 90.0, VARY, ["SD", "SPT"], root / "costs.toml", 0.95, 3, 12, 1, "simpy"
    )
    return root, d


def test_the_choice_meets_the_target_and_nothing_clearly_feasible_is_cheaper(
    designed: tuple[Path, dict],
) -> None:
    root, d = designed
    assert d["choice"] is not None, d["text"]
    assert d["ci_low"] >= 90.0 and d["configurations"] == 20
    assert set(d["choice"]) == {"robots.count", "robots.arm_speed", "policy"}
    assert d["runs"] < d["runs_fixed"]  # replications only where the decision was open
    sc = load_scenario(BASELINE, overrides=LINE)
    seeds = replication_seeds(sc.seed + 77, 8)  # brute force, other seeds

    def brute(row: dict) -> tuple[float, float]:
        values = {k: v for k, v in row["choice"].items() if k != "policy"}
        ev = Evaluator(root / "brute", [row["choice"]["policy"]], seeds, [], 1, "simpy")
        runs = ev.runs([with_overrides(sc, values)], [str(values)])[0]
        mean, low, _ = t_interval([r["gripping_rate"] for r in runs[row["choice"]["policy"]]])
        return mean, low

    mean, _ = brute({"choice": d["choice"]})
    assert mean >= 90.0
    cheaper = [r for r in d["rows"] if r["total_cost"] < d["total_cost"] - 1e-6]
    for row in cheaper:  # no configuration cheaper than the choice is clearly feasible
        _, low = brute(row)
        assert low < 90.0, row["choice"]


def test_json_keys_and_asking_again_reuses_the_runs(designed: tuple[Path, dict]) -> None:
    root, d = designed
    out = root / "d"
    args = ["design", str(BASELINE), "--target", "85", "--out", str(out), "--costs"]
    args += [str(root / "costs.toml"), "-p", "SD", "-p", "SPT", "--max-replications", "12"]
    for v in VARY:
        args += ["--vary", v]
    for k, v in LINE.items():
        args += ["--set", f"{k}={v}"]
    result = CliRunner().invoke(app, [*args, "--workers", "1", "--engine", "simpy", "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert {"choice", "gripping_rate", "ci_low", "total_cost", "alternatives"} <= set(data)
    for a in data["alternatives"]:
        assert {"choice", "gripping_rate", "ci_low", "total_cost"} <= set(a)
    assert data["simulated"] < data["runs"]  # the 90 % question's runs are reused
    assert (out / "report.html").is_file()


def test_vary_and_cost_file_mistakes_are_one_line(tmp_path: Path) -> None:
    assert parse_vary("robots.count=3:5") == ("robots.count", [3, 4, 5])
    assert parse_vary("robots.arm_speed=3,4.5") == ("robots.arm_speed", [3, 4.5])
    with pytest.raises(StudyError, match="not a scenario field"):
        parse_vary("robots.arm_sped=3,4")
    with pytest.raises(StudyError, match="whole numbers"):
        parse_vary("robots.count=2:x")
    bad = tmp_path / "c.toml"
    bad.write_text("robot_price = 1\nbelt_price = 1\nhours = 1\n")
    with pytest.raises(StudyError, match="lost_part_cost is missing"):
        read_costs(bad)
    bad.write_text("robot_price = -1\nbelt_price = 1\nhours = 1\nlost_part_cost = 0\n")
    with pytest.raises(StudyError, match="robot_price = -1 is not allowed; give a number from 0"):
        read_costs(bad)


def test_each_look_at_an_interval_is_paid_for(designed: tuple[Path, dict]) -> None:
    """Judging a configuration after 3, 6 and 12 replications and stopping at the first
    crossing is three looks: each interval is taken at 1 - 0.05 / (K x 3), K = 5 counts x
    2 speeds x 2 rules, so the pick keeps 95 % after the sequential rounds too."""
    from pnp_twin.studies.design import looks

    assert [looks(3, 3), looks(3, 6), looks(3, 12), looks(3, 24), looks(5, 30)] == [1, 2, 3, 4, 4]
    _, d = designed
    assert d["confidence_each"] == pytest.approx(1 - 0.05 / (5 * 2 * 2 * looks(3, 12)))
