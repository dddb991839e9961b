"""``pnp-twin design`` with a continuous range: optuna's constrained TPE picks the arm speed
on a made-up line; the choice meets the target with other seeds and no point of a brute-force
grid over the same range is clearly feasible and clearly cheaper; asking again simulates
nothing; mistakes are one line and write nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.design import Continuous, parse_vary, run_design
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
belt_price = 0
lost_part_cost = 0.01
hours = 100
[robot_price]
"2.0" = 20000
"6.0" = 40000
"""
VARY = ["robots.count=2:3", "robots.arm_speed=2.0:6.0"]
TARGET = 85.0


@pytest.fixture(scope="module")
def designed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    root = tmp_path_factory.mktemp("design_cont")
    (root / "costs.toml").write_text(COSTS)
    sc = load_scenario(BASELINE, overrides=LINE)
    d = run_design(
        sc,
        root / "d",
        TARGET,
        VARY,
        ["SD"],
        root / "costs.toml",
        0.95,
        3,
        24,
        1,
        "simpy",
        trials=15,
    )
    return root, d


def test_parse_continuous() -> None:
    assert parse_vary("robots.arm_speed=2.0:6") == ("robots.arm_speed", Continuous(2.0, 6.0))
    assert parse_vary("robots.count=2:4") == ("robots.count", [2, 3, 4])


def test_the_optimiser_meets_the_target_and_a_grid_does_not_clearly_beat_it(
    designed: tuple[Path, dict],
) -> None:
    root, d = designed
    assert d["choice"] is not None, d["text"]
    assert d["continuous"] == ["robots.arm_speed"] and d["trials"] == 15
    assert d["configurations"] == 2 * 15 and d["ci_low"] >= TARGET
    speed = d["choice"]["robots.arm_speed"]
    assert 2.0 <= speed <= 6.0 and f"{speed:g} m/s" in d["text"]
    sc = load_scenario(BASELINE, overrides=LINE)
    seeds = replication_seeds(sc.seed + 77, 8)  # an independent check, other seeds
    ev = Evaluator(root / "brute", ["SD"], seeds, [], 1, "simpy")

    def brute(count: int, arm: float) -> tuple[float, float, float]:
        values = {"robots.count": count, "robots.arm_speed": arm}
        runs = ev.runs([with_overrides(sc, values)], [str(values)])[0]["SD"]
        mean, low, _ = t_interval([r["gripping_rate"] for r in runs])
        lost = 0.01 * 4.0 * (1 - mean / 100) * 3600 * 100  # lost parts over 100 h at 4 parts/s
        price = 20000 + 5000 * (arm - 2.0)  # the cost file's table, interpolated
        return mean, low, count * price + lost

    mean, _, _ = brute(d["choice"]["robots.count"], speed)
    assert mean >= TARGET
    grid = [(n, 2.0 + 0.25 * i) for n in (2, 3) for i in range(17)]
    for n, arm in grid:
        _, low, cost = brute(n, arm)
        # a grid point both clearly feasible and clearly (over 5 %) cheaper would beat it
        assert not (low >= TARGET and cost < 0.95 * d["total_cost"]), (n, arm, low, cost)


def test_asking_again_simulates_nothing_and_the_cli_reports_the_speed(
    designed: tuple[Path, dict],
) -> None:
    root, d = designed
    args = ["design", str(BASELINE), "--target", str(TARGET), "--out", str(root / "d")]
    args += ["--costs", str(root / "costs.toml"), "-p", "SD", "--trials", "15"]
    for v in VARY:
        args += ["--vary", v]
    for k, v in LINE.items():
        args += ["--set", f"{k}={v}"]
    result = CliRunner().invoke(app, [*args, "--workers", "1", "--engine", "simpy", "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["simulated"] == 0 and data["replayed"] > 0
    assert data["choice"] == d["choice"] and data["total_cost"] == pytest.approx(d["total_cost"])
    html = (root / "d" / "report.html").read_text()
    assert "constrained TPE" in html


@pytest.mark.parametrize(
    ("vary", "extra", "message"),
    [
        ("robots.count=2.0:4.0", [], "whole-number field"),
        ("robots.arm_speed=6.0:2.0", [], "LO < HI"),
        ("robots.arm_speed=1.0:6.0", [], "no price for 1 m/s"),
        ("robots.arm_speed=2.0:6.0", ["--trials", "1"], "--trials"),
    ],
)
def test_mistakes_are_one_line_and_write_nothing(
    tmp_path: Path, vary: str, extra: list[str], message: str
) -> None:
    (tmp_path / "costs.toml").write_text(COSTS)
    out = tmp_path / "d"
    args = ["design", str(BASELINE), "--target", "80", "--out", str(out), "--vary", vary]
    args += ["--costs", str(tmp_path / "costs.toml"), *extra]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = [x for x in result.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0], lines
    assert not out.exists()
