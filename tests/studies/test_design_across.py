"""``design --across``: a choice that meets the target at every condition the line will see,
with the confidence holding jointly (Bonferroni over the conditions too); a condition given
to ``--vary`` is refused with the hint (issue #32)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.design import looks, run_design
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.stats import t_interval

ROOT = Path(__file__).resolve().parents[2]
LINE = {"duration": 60.0, "warmup": 10.0, "seed": 5, "belt.length": 3.0, "feeder.rate": 4.0}
FLOWS = [3.0, 5.0, 7.0]


@pytest.fixture(scope="module")
def designed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    root = tmp_path_factory.mktemp("across")
    sc = load_scenario(ROOT / "scenarios" / "paper_baseline.toml", overrides=LINE)
    d = run_design(
        sc,
        root / "d",
        90.0,
        ["robots.count=2:7"],
        ["SD"],
        None,
        0.95,
        3,
        12,
        1,
        "simpy",
        across=[f"feeder.rate={','.join(map(str, FLOWS))}"],
    )
    return root, d


def test_the_choice_meets_the_target_at_every_listed_flow_by_brute_force(
    designed: tuple[Path, dict],
) -> None:
    root, d = designed
    assert d["choice"] is not None, d["text"]
    assert [c["feeder.rate"] for c in d["conditions"]] == FLOWS
    sc = load_scenario(ROOT / "scenarios" / "paper_baseline.toml", overrides=LINE)
    seeds = replication_seeds(sc.seed + 99, 10)  # other seeds than the design's
    n = d["choice"]["robots.count"]
    for flow in FLOWS:
        ev = Evaluator(root / "brute", ["SD"], seeds, [], 1, "simpy")
        line = with_overrides(sc, {"robots.count": n, "feeder.rate": flow})
        g = [r["gripping_rate"] for r in ev.runs([line], ["b"])[0]["SD"]]
        assert t_interval(g)[0] >= 90.0, (flow, g)
    assert "at each of 3 conditions" in d["text"]
    # the lowest flow alone would have bought less: the conditions are what decides
    low = with_overrides(sc, {"feeder.rate": FLOWS[0]})
    alone = run_design(low, root / "low", 90.0, ["robots.count=2:7"], ["SD"], None, 0.95, 3, 12)
    assert alone["choice"]["robots.count"] < n


def test_the_confidence_holds_jointly_over_the_conditions(designed: tuple[Path, dict]) -> None:
    _, d = designed
    assert d["confidence_each"] == pytest.approx(1 - 0.05 / (6 * looks(3, 12) * 3))
    assert d["runs"] == sum(r["replications"] for r in d["rows"]) * 3


def test_a_condition_given_to_vary_is_refused_with_the_hint(tmp_path: Path) -> None:
    args = ["design", "paper_baseline", "--target", "90", "--vary", "robots.count=2:4"]
    result = CliRunner().invoke(
        app, [*args, "--vary", "feeder.rate=6,7,8", "--out", str(tmp_path / "o")]
    )
    assert result.exit_code == 2
    assert "give it with --across feeder.rate=6,7,8" in result.stderr
    assert not (tmp_path / "o").exists()
    bad = CliRunner().invoke(app, [*args, "--across", "feeder.rat=6", "--out", str(tmp_path / "o")])
    assert bad.exit_code == 2 and "not a scenario field" in bad.stderr
    assert not (tmp_path / "o").exists()


def test_size_across_meets_every_condition_and_writes_the_chosen_line(tmp_path: Path) -> None:
    chosen = tmp_path / "sized.toml"
    args = ["size", "paper_baseline", "--target", "90", "--set", "duration=60"]
    args += ["--set", "warmup=10", "--set", 'sweep.grid={"robots.count": [3, 4, 5, 6]}']
    args += ["--across", "feeder.rate=5,8", "-r", "3", "--workers", "1", "--no-report"]
    result = CliRunner().invoke(
        app, [*args, "--out", str(tmp_path / "s"), "--write-scenario", str(chosen)]
    )
    assert result.exit_code == 0, result.output
    import json

    sizing = json.loads((tmp_path / "s" / "sizing.json").read_text())
    assert [c["feeder.rate"] for c in sizing["by_condition"]] == [5.0, 8.0]
    assert sizing["answer"] == max(c["answer"] for c in sizing["by_condition"])
    line = load_scenario(chosen)
    assert line.robots.count == sizing["answer"] and line.policy == sizing["rule"]
    twice = CliRunner().invoke(
        app, [*args, "--across", "robots.count=3,4", "--out", str(tmp_path / "t")]
    )
    assert twice.exit_code == 2 and "already in sweep.grid" in twice.stderr


def test_across_a_folder_of_shift_traces_runs_each_and_says_what_the_interval_covers(
    tmp_path: Path,
) -> None:
    import pandas as pd

    trace = pd.read_csv(ROOT / "scenarios" / "traces" / "sample_line.csv")
    (tmp_path / "shifts").mkdir()
    trace.to_csv(tmp_path / "shifts" / "a.csv", index=False)
    trace.iloc[::2].to_csv(tmp_path / "shifts" / "b.csv", index=False)  # a quieter shift
    sc = load_scenario(ROOT / "scenarios" / "trace_replay.yaml", {"belt.length": 4.0})
    d = run_design(
        sc, tmp_path / "d", 90.0, ["robots.count=2:4"], ["SD"], None, 0.95, 3, 6,
        across=[f"feeder.trace={tmp_path / 'shifts'}"],
    )  # fmt: skip
    assert [Path(c["feeder.trace"]).name for c in d["conditions"]] == ["a.csv", "b.csv"]
    assert "replayed as recorded" in d["text"]
    assert d["choice"] is not None


def test_another_set_of_conditions_is_another_question(tmp_path: Path) -> None:
    """A finished design is read back only for the same question: the conditions are part
    of it, so other flows are searched (their runs at the shared flow from the store)."""
    sc = load_scenario(ROOT / "scenarios" / "paper_baseline.toml", overrides=LINE)
    ask = ["robots.count=2:4"], ["SD"], None, 0.95, 3, 6

    first = run_design(sc, tmp_path / "d", 90.0, *ask, across=["feeder.rate=3,5"])
    again = run_design(sc, tmp_path / "d", 90.0, *ask, across=["feeder.rate=3,5"])
    other = run_design(sc, tmp_path / "d", 90.0, *ask, across=["feeder.rate=3,7"])
    assert again["runs_simulated"] == 0 and again["question"] == first["question"]
    assert other["question"] != first["question"]
    assert [c["feeder.rate"] for c in other["conditions"]] == [3.0, 7.0]
    assert 0 < other["runs_simulated"] < other["runs"]  # flow 3's runs came from the store
