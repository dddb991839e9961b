"""A finished design asked the same question again reads its answer back without searching;
another question (target, prices) searches again, its runs read from the store."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pnp_twin.studies import design
from pnp_twin.studies.design import run_design
from pnp_twin.twin.loader import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "feeder.rate": 4.0, "duration": 20.0, "warmup": 4.0, "seed": 5}
VARY = ["robots.count=1:2", "robots.arm_speed=2.0:6.0"]
COSTS = 'belt_price = 0\nlost_part_cost = 0.01\nhours = 100\n[robot_price]\n"2.0" = 1\n"6.0" = 3\n'


def ask(out: Path, costs: Path, target: float = 80.0) -> dict:
    sc = load_scenario(BASELINE, overrides=LINE)
    return run_design(sc, out, target, VARY, ["SD"], costs, 0.95, 2, 4, 1, "simpy", trials=4)


def test_the_same_question_is_read_back_and_another_is_searched(tmp_path, monkeypatch) -> None:
    costs = tmp_path / "costs.toml"
    costs.write_text(COSTS)
    out = tmp_path / "d"
    first = ask(out, costs)
    assert first["simulated"] > 0

    def no_search(*args: object, **kwargs: object) -> None:
        raise AssertionError("searched again")

    real = design._optimise
    monkeypatch.setattr(design, "_optimise", no_search)
    again = ask(out, costs)
    assert (again["simulated"], again["replayed"]) == (0, first["runs"])
    volatile = ("wall_time", "simulated", "replayed", "runs_simulated", "runs_replayed")
    assert {k: v for k, v in again.items() if k not in volatile} == {
        k: v for k, v in first.items() if k not in volatile
    }
    with pytest.raises(AssertionError, match="searched again"):
        ask(out, costs, target=85.0)  # another target: another question
    costs.write_text(COSTS.replace('"6.0" = 3', '"6.0" = 4'))
    with pytest.raises(AssertionError, match="searched again"):
        ask(out, costs)  # the same file name with another price
    monkeypatch.setattr(design, "_optimise", real)
    priced = ask(out, costs)
    assert priced["simulated"] < priced["runs"]  # its runs came from the store
    (out / "design.json").write_text("{damaged")
    assert ask(out, costs)["choice"] == priced["choice"]  # searched again, same answer
    assert json.loads((out / "design.json").read_text())["question"] == priced["question"]
