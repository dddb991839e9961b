"""``pnp-twin capacity --vary``: one root-finding search per configuration, checked against a
brute-force grid of flows with other seeds on a made-up line; the JSON keeps the first
configuration's answer at the top and adds ``configurations``; mistakes write nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.capacity import run_capacity
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario, with_overrides

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "feeder.rate": 3.0, "duration": 60.0, "warmup": 10.0, "seed": 4}
TARGET = 80.0


@pytest.fixture(scope="module")
def found(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    folder = tmp_path_factory.mktemp("capacity_vary") / "cap"
    sc = load_scenario(BASELINE, overrides=LINE)
    c = run_capacity(sc, folder, TARGET, 0.95, ["SD"], 4, 1, "simpy", vary=["robots.count=2:3"])
    return folder, c


def test_each_configuration_against_a_brute_force_grid(found: tuple[Path, dict]) -> None:
    folder, c = found
    configs = c["configurations"]
    assert [x["choice"] for x in configs] == [{"robots.count": 2}, {"robots.count": 3}]
    assert (c["max_rate"], c["ci_low"], c["ci_high"]) == tuple(
        configs[0][k] for k in ("max_rate", "ci_low", "ci_high")
    )
    assert configs[1]["ci_low"] > configs[0]["ci_low"]  # a third robot sustains more flow
    sc = load_scenario(BASELINE, overrides=LINE)
    ev = Evaluator(folder / "brute", ["SD"], replication_seeds(sc.seed + 99, 6), [], 1, "simpy")
    for one in configs:
        assert one["search"]["max_rate"] == "found" and one["ci_low"] <= one["ci_high"]
        line = with_overrides(sc, one["choice"])
        grid = [one["max_rate"] * (0.6 + 0.1 * i) for i in range(9)]  # 0.6x to 1.4x
        scenarios = [with_overrides(line, {"feeder.rate": round(r, 4)}) for r in grid]
        means = [p.mean["gripping_rate"] for p in ev.predict(scenarios, [str(r) for r in grid])]
        met = [r for r, m in zip(grid, means, strict=True) if m >= TARGET]
        assert met, one
        best = max(met)  # the brute-force capacity, other seeds, to one grid step
        step = 0.1 * one["max_rate"]
        assert one["ci_low"] - step <= best <= one["ci_high"] + step, (one, grid, means)


def test_cli_json_has_configurations_and_a_report_with_every_curve(tmp_path: Path) -> None:
    out = tmp_path / "cap"
    args = ["capacity", str(BASELINE), "--target", "70", "--out", str(out), "-r", "2"]
    args += ["--vary", "robots.count=2,3"]
    for s in ["robots.count=2", "duration=30", "warmup=5", "feeder.rate=3", "seed=2"]:
        args += ["--set", s]
    result = CliRunner().invoke(app, [*args, "--workers", "1", "--engine", "simpy", "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert {"max_rate", "ci_low", "ci_high", "configurations"} <= set(data)
    assert len(data["configurations"]) == 2
    for one in data["configurations"]:
        assert {"choice", "max_rate", "ci_low", "ci_high", "policy"} <= set(one)
        assert "curve" not in one
    html = (out / "report.html").read_text()
    assert "per configuration" in html and "Upper crossing" in html


@pytest.mark.parametrize(
    ("vary", "message"),
    [
        ("robots.arm_speed=2.0:6.0", "a continuous range is for design"),
        ("feeder.rate=2,3", "what capacity searches"),
        ("robots.cont=2,3", "not a scenario field"),
        ("robots.count=0,2", "--vary"),
    ],
)
def test_mistakes_are_one_line_and_write_nothing(tmp_path: Path, vary: str, message: str) -> None:
    out = tmp_path / "cap"
    args = ["capacity", str(BASELINE), "--target", "80", "--out", str(out), "--vary", vary]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = [x for x in result.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0], lines
    assert not out.exists()
