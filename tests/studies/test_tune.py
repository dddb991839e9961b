"""``pnp-twin tune``: the balancing settings to type into the controller, and how sure.

Its answer, run again as a plain policy, gives what the report promises; a target is met
with the fewest parts passed on; bad questions are one line, exit 2, no folder written.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies import make_policy
from pnp_twin.studies.tune import Scored, objective
from pnp_twin.twin import simulate
from pnp_twin.twin.loader import load_scenario

SMALL = ["--duration", "40", "--trials", "6", "--tuning-seeds", "2", "--seeds", "4"]


def tune(tmp_path: Path, *args: str) -> tuple[int, str]:
    """Exit code, and stdout (the JSON) or, on a refusal, what was said (stderr)."""
    res = CliRunner().invoke(app, ["tune", "paper_baseline", *SMALL, *args, "--json"])
    return res.exit_code, res.stdout if res.exit_code == 0 else res.output


@pytest.mark.parametrize("strategy", ["share", "lane"])
def test_the_answer_run_again_gives_what_the_report_promises(tmp_path: Path, strategy: str) -> None:
    out = tmp_path / strategy
    code, text = tune(tmp_path, "--strategy", strategy, "--rule", "SPT", "--out", str(out))
    assert code == 0, text
    data = json.loads(text)
    assert {p.name for p in out.iterdir()} >= {"tune.json", "trials.csv", "report.html"}
    assert data["policy"].startswith(f"{strategy}:") and data["policy"].endswith(";rule=SPT")
    assert data["controller"].startswith("robot 1: ")
    assert len(pd.read_csv(out / "trials.csv")) == 6
    # the same seeds, the same numbers: the answer is a plain policy anyone can run
    sc = load_scenario("paper_baseline", {"duration": 40.0, "warmup": 8.0})
    again = [
        simulate(sc, make_policy(data["policy"], 4), seed=s).kpis["gripping_rate"]
        for s in data["seeds"]
    ]
    assert np.mean(again) == pytest.approx(data["tuned"]["gripping_rate"], abs=1e-9)
    # and on fresh seeds it stays within what the interval promises (its width again)
    fresh = [
        simulate(sc, make_policy(data["policy"], 4), seed=s).kpis["gripping_rate"]
        for s in range(100, 108)
    ]
    low, high = data["tuned"]["ci_low"], data["tuned"]["ci_high"]
    half = (high - low) / 2
    assert low - half <= float(np.mean(fresh)) <= high + half
    html = (out / "report.html").read_text()
    assert data["controller"] in html and "best rule" in html and "lookahead" in html


def test_a_target_is_met_with_the_fewest_parts_passed_on() -> None:
    met_many = Scored("a", [80.0, 82.0], [300.0, 320.0])
    met_few = Scored("b", [78.0, 79.0], [100.0, 120.0])
    missed = Scored("c", [70.0, 75.0], [0.0, 0.0])
    ranked = sorted([met_many, met_few, missed], key=lambda s: -objective(s, 77.0))
    assert [s.policy for s in ranked] == ["b", "a", "c"]
    assert max([met_many, met_few, missed], key=lambda s: objective(s, None)).policy == "a"


BAD = [
    (["--strategy", "zigzag"], "--strategy: 'zigzag' is not allowed; allowed share, lane"),
    (["--target", "150"], "--target: 150 is outside 0..100"),
    (["--rule", "XYZ"], "--rule: 'XYZ' is not a rule"),
    (["--set", "robots.count=1"], "has one robot; there is nothing to balance"),
]


@pytest.mark.parametrize(("args", "message"), BAD)
def test_bad_questions_are_one_line_and_write_nothing(
    tmp_path: Path, args: list[str], message: str
) -> None:
    out = tmp_path / "t"
    code, text = tune(tmp_path, *args, "--out", str(out))
    assert code == 2
    lines = text.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]
    assert not out.exists()


def test_the_tuned_line_written_as_a_scenario_runs_as_the_answer_promised(
    tmp_path: Path,
) -> None:
    """--write-scenario: the line with the tuned policy and the first evaluation seed;
    `run` on it gives that seed's G exactly (issue #32)."""
    chosen = tmp_path / "tuned.toml"
    args = ["--strategy", "share", "--out", str(tmp_path / "t"), "--write-scenario", str(chosen)]
    code, text = tune(tmp_path, *args)
    assert code == 0, text
    data = json.loads(text)
    line = load_scenario(chosen)
    assert line.policy == data["policy"] and line.seed == data["seeds"][0]
    first = simulate(line, make_policy(line.policy, line.robots.count)).kpis["gripping_rate"]
    sc = load_scenario("paper_baseline", {"duration": 40.0, "warmup": 8.0})
    same = simulate(sc, make_policy(data["policy"], 4), seed=data["seeds"][0])
    assert first == same.kpis["gripping_rate"]
