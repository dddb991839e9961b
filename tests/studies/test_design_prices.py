"""``design`` priced per robot (an overridden robot at its own speed, owned robots at 0), its
cost with an interval, capital and running apart, per part and against today's line, and
the choice written as a scenario file that ``run`` reproduces (issue #32)."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies import make_policy
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.design import run_design
from pnp_twin.studies.design_text import line_notes
from pnp_twin.studies.prices import capital, read_costs, robot_prices
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.run import simulate
from pnp_twin.twin.stats import t_interval

LINE = """duration = 60.0
warmup = 10.0
seed = 5
[feeder]
rate = 4.0
[belt]
length = 3.0
[robots]
count = 3
[[robots.overrides]]
robot = 2
arm_speed = 1.5
"""
PRICES = {1.5: 15000.0, 2.0: 20000.0, 4.0: 26000.0}
COSTS = """belt_price = 5000
lost_part_cost = 0.02
hours = 2000
[robot_price]
"1.5" = 15000
"2.0" = 20000
"4.0" = 26000
"""
VARY = ["robots.count=2:4", "robots.arm_speed=2.0,4.0"]
TARGET = 90.0


@pytest.fixture(scope="module")
def designed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    root = tmp_path_factory.mktemp("prices")
    (root / "line.toml").write_text(LINE)
    (root / "costs.toml").write_text(COSTS)
    sc = load_scenario(root / "line.toml")
    d = run_design(
        sc,
        root / "d",
        TARGET,
        VARY,
        ["SD"],
        root / "costs.toml",
        0.95,
        3,
        12,
        1,
        "simpy",
        baseline=load_scenario(root / "line.toml"),
    )
    return root, d


def test_each_robot_is_priced_at_its_own_speed(designed: tuple[Path, dict]) -> None:
    _, d = designed
    for row in d["rows"]:
        n, speed = row["choice"]["robots.count"], row["choice"]["robots.arm_speed"]
        own = [PRICES[1.5] if i == 2 else PRICES[speed] for i in range(1, n + 1)]
        assert row["robot_prices"] == own
        lost = row["lost_parts_cost"]
        assert row["total_cost"] == pytest.approx(sum(own) + 5000 + lost)
    assert "robot 2 arm speed 1.5 m/s" in d["text"]
    from pnp_twin.reports.design import bill_table

    bill = re.sub(r"<[^>]+>", "|", bill_table(d))
    assert re.search(r"Robot 2\|+1\.5 m/s\|+15,000", bill), bill
    assert f"{d['capital_cost']:,.0f}" in bill


def test_the_choice_equals_a_brute_force_over_every_configuration(
    designed: tuple[Path, dict],
) -> None:
    """Every configuration run 12 times (the most), judged at the same level, priced per
    robot by hand: the cheapest that meets the target is the design's choice."""
    root, d = designed
    sc = load_scenario(root / "line.toml")
    seeds = replication_seeds(sc.seed, 12)
    best = None
    for n in (2, 3, 4):
        for speed in (2.0, 4.0):
            line = with_overrides(sc, {"robots.count": n, "robots.arm_speed": speed})
            ev = Evaluator(root / "brute", ["SD"], seeds, ["part_flow"], 1, "simpy")
            runs = ev.runs([line], ["brute"])[0]["SD"]
            g = [r["gripping_rate"] for r in runs]
            _, low, _ = t_interval(g, d["confidence_each"])
            flow = sum(r["part_flow"] for r in runs) / len(runs)
            lost = 0.02 * flow * (1 - sum(g) / len(g) / 100) * 3600 * 2000
            cost = sum(PRICES[1.5] if i == 2 else PRICES[speed] for i in range(1, n + 1))
            cost += 5000 + lost
            if low >= TARGET and (best is None or cost < best[0]):
                best = (cost, {"robots.count": n, "robots.arm_speed": speed})
    assert best is not None
    assert {k: v for k, v in d["choice"].items() if k != "policy"} == best[1]


def test_owned_robots_are_priced_zero_but_still_counted(tmp_path: Path) -> None:
    (tmp_path / "c.toml").write_text("owned = [2, 3]\n" + COSTS)
    (tmp_path / "line.toml").write_text(LINE)
    costs = read_costs(tmp_path / "c.toml")
    sc = with_overrides(load_scenario(tmp_path / "line.toml"), {"robots.count": 4})
    # 3 m/s (the line's speed) lies between 2 and 4: 23,000; robot 2 (1.5 m/s) and 3 owned
    assert robot_prices(costs, sc) == [23000.0, 0.0, 0.0, 23000.0]
    assert capital(costs, sc) == 2 * 23000 + 5000
    assert line_notes(sc, costs["owned"])[-1] == "robots 2, 3 already owned"


def test_the_cost_has_its_interval_capital_running_and_per_part(
    designed: tuple[Path, dict],
) -> None:
    _, d = designed
    assert d["total_cost_low"] < d["total_cost"] < d["total_cost_high"]
    assert d["capital_cost"] + d["running_cost"] == pytest.approx(d["total_cost"])
    assert d["cost_per_part"] > 0
    assert f"[{d['total_cost_low']:,.0f}, {d['total_cost_high']:,.0f}]" in d["text"]
    assert f"capital {d['capital_cost']:,.0f}; running {d['running_cost']:,.0f}" in d["text"]
    assert "per part gripped" in d["text"]


def test_payback_against_todays_line(designed: tuple[Path, dict]) -> None:
    _, d = designed
    p = d["payback"]
    assert p["saving_low"] <= p["saving_per_year"] <= p["saving_high"]
    assert p["saving_per_year"] > 0  # today's line has one slow robot of three: it loses more
    assert p["payback_months"] == pytest.approx(12 * d["capital_cost"] / p["saving_per_year"])
    assert p["payback_months_low"] <= p["payback_months"]
    assert f"back in {p['payback_months']:.1f} months" in d["text"]
    assert p["replications"] == d["replications"]  # paired over the choice's replications


def test_the_written_scenario_reproduces_the_choice(tmp_path: Path) -> None:
    (tmp_path / "line.toml").write_text(LINE)
    (tmp_path / "costs.toml").write_text(COSTS)
    chosen = tmp_path / "chosen.toml"
    args = ["design", str(tmp_path / "line.toml"), "--target", "90", "-p", "SD"]
    args += [f"--vary={v}" for v in VARY] + ["--costs", str(tmp_path / "costs.toml")]
    args += ["--workers", "1", "--engine", "simpy", "--no-report"]
    out = ["--out", str(tmp_path / "d")]
    result = CliRunner().invoke(app, [*args, *out, "--write-scenario", str(chosen)])
    assert result.exit_code == 0, result.output
    d = json.loads((tmp_path / "d" / "design.json").read_text())
    line = load_scenario(chosen)
    assert line.policy == d["choice"]["policy"] and line.seed == d["seeds"][0]
    assert line.robots.count == d["choice"]["robots.count"]
    assert line.robots.param(2, "arm_speed") == 1.5  # the override goes with the line
    run = simulate(line, make_policy(line.policy, line.robots.count), engine="simpy").kpis
    ev = Evaluator(tmp_path / "d", ["SD"], d["seeds"][:1], ["part_flow"], 1, "simpy")
    values = {k: v for k, v in d["choice"].items() if k != "policy"}
    base = load_scenario(tmp_path / "line.toml")
    stored = ev.runs([with_overrides(base, values)], ["again"])[0]["SD"][0]
    assert ev.runs_simulated == 0  # read back from the design's own journal
    assert run["gripping_rate"] == stored["gripping_rate"]
    assert run["part_flow"] == stored["part_flow"]
    # asking again replaces our own file; a file of the user's is refused, nothing written
    again = CliRunner().invoke(app, [*args, *out, "--write-scenario", str(chosen)])
    assert again.exit_code == 0, again.output
    theirs = tmp_path / "theirs.toml"
    theirs.write_text("seed = 1\n")
    refused = CliRunner().invoke(
        app, [*args, "--out", str(tmp_path / "d2"), "--write-scenario", str(theirs)]
    )
    assert refused.exit_code == 2 and "was not written by pnp-twin" in refused.stderr
    assert theirs.read_text() == "seed = 1\n" and not (tmp_path / "d2").exists()


BAD = {
    "inf": ("robot_price = inf", "robot_price = inf is not allowed"),
    "negative": ("robot_price = -5", "robot_price = -5 is not allowed"),
    "huge": ("robot_price = 1e308", "robot_price = 1e+308 is not allowed"),
    "duplicate": ('[robot_price]\n"3" = 1\n"3.0" = 2', 'speeds "3" and "3.0" are the same'),
    "negative key": ('[robot_price]\n"-3" = 1', "speed '-3' is not allowed"),
    "inf key": ('[robot_price]\n"inf" = 1', "speed 'inf' is not allowed"),
    "owned": ("robot_price = 1\nowned = [2, 2]", "owned = [2, 2] is not allowed"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_cost_file_is_one_line_naming_file_key_and_value(tmp_path: Path, case: str) -> None:
    text, message = BAD[case]
    costs = tmp_path / "costs.toml"
    costs.write_text("belt_price = 1\nlost_part_cost = 0.1\nhours = 10\n" + text + "\n")
    args = ["design", "paper_baseline", "--target", "50", "--vary", "robots.count=1:2"]
    args += ["--costs", str(costs), "--out", str(tmp_path / "o"), "--no-report"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = [x for x in result.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and str(costs) in lines[0] and message in lines[0], lines
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("kind", ["fifo", "zero"])
def test_a_cost_file_that_is_a_fifo_or_dev_zero_is_refused_not_hung(
    tmp_path: Path, kind: str
) -> None:
    costs = tmp_path / "costs.toml"
    if kind == "fifo":
        os.mkfifo(costs)
    else:
        costs.symlink_to("/dev/zero")
    args = ["design", "paper_baseline", "--target", "50", "--vary", "robots.count=1:2"]
    result = CliRunner().invoke(app, [*args, "--costs", str(costs), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and "give a regular file" in result.stderr, result.output
    assert not (tmp_path / "o").exists()


def test_an_overridden_robot_outside_the_price_table_is_refused(tmp_path: Path) -> None:
    (tmp_path / "line.toml").write_text(LINE.replace("arm_speed = 1.5", "arm_speed = 1.2"))
    (tmp_path / "costs.toml").write_text(COSTS)
    args = ["design", str(tmp_path / "line.toml"), "--target", "90", "-p", "SD"]
    args += [f"--vary={v}" for v in VARY] + ["--costs", str(tmp_path / "costs.toml")]
    result = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    assert "no price for 1.2 m/s (robot 2's arm speed)" in result.stderr
    assert not (tmp_path / "o").exists() and math.isfinite(1.0)
