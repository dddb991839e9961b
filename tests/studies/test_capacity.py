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
    assert again["runs_simulated"] < again["runs_replayed"] and again["runs_replayed"] > 0
    assert "simulated" not in again and "replayed" not in again  # those counted flows
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


class TwoRules:
    """A made-up evaluator: G falls linearly in the flow; rule A is precise (G = 100 - 5 f
    +- 0.1), rule B has the higher mean but a wide spread (G = 100 - 4 f +- 10)."""

    policies = ("A", "B")

    def runs(self, scenarios, labels):
        spread = (-1.0, -0.5, 0.0, 0.5, 1.0)
        out = []
        for sc in scenarios:
            f = sc.feeder.rate
            a = [{"gripping_rate": min(100.0, 100 - 5 * f + 0.1 * d)} for d in spread]
            b = [{"gripping_rate": min(100.0, 100 - 4 * f + 10 * d)} for d in spread]
            out.append({"A": a, "B": b})
        return out


def test_each_crossing_is_the_best_rules_and_names_the_promises_rule() -> None:
    """With several rules, the mean and upper crossings are the highest over the rules (not
    the rule with the best lower bound's), and the promise names its rule."""
    from pnp_twin.studies.capacity import CRITERIA, Capacity
    from pnp_twin.twin.stats import t_interval

    sc = load_scenario(BASELINE, overrides={**LINE, "feeder.rate": 2.0})
    cap = Capacity(sc, TwoRules(), 80.0, 0.95)  # type: ignore[arg-type]
    cross = {name: cap.crossing(key, 2.0)[0] for name, key in CRITERIA.items()}
    _, low_b, high_b = t_interval([10 * d for d in (-1, -0.5, 0, 0.5, 1)], cap.level)
    assert cross["max_rate"] == pytest.approx(5.0, rel=0.02)  # B's mean crossing, not A's 4
    assert cross["ci_high"] == pytest.approx((20 + high_b) / 4, rel=0.02)  # B's upper one
    assert cross["ci_low"] == pytest.approx(4.0, rel=0.02)  # A's promise beats B's
    assert (20 + low_b) / 4 < 3.0  # B's own promise is far lower
    assert cap.rule_at(cross["ci_low"], "low") == "A"
    assert cap.rule_at(cross["max_rate"], "mean") == "B"
    assert cap.rule_at(cross["ci_high"], "high") == "B"


def test_the_json_and_sentence_say_which_rule_the_promise_is_for() -> None:
    from pnp_twin.studies.capacity import capacity_text

    c = {
        "choice": {}, "robots": 2, "confidence": 0.95, "target": 80.0, "max_rate": 5.0,
        "ci_low": 3.98, "ci_high": 8.9, "policy": "A",
        "policies": {"max_rate": "B", "ci_low": "A", "ci_high": "B"},
        "search": {"max_rate": "found", "ci_low": "found", "ci_high": "found"},
    }  # fmt: skip
    text = capacity_text(c)
    assert "running A you can promise 3.98 parts/s at G ≥ 80 % with 95 % confidence" in text
    assert "after picking the rule; the mean (B's) crosses at 5 parts/s" in text
    assert "above 8.9 parts/s the line misses it with 95 % confidence" in text


def test_with_two_rules_the_promise_holds_for_its_rule_with_other_seeds(tmp_path: Path) -> None:
    """Brute force with independent seeds: at the promised flow the rule it names meets the
    target; well past the upper crossing no rule does."""
    sc = load_scenario(BASELINE, overrides=LINE)
    c = run_capacity(sc, tmp_path / "cap", 80.0, 0.95, ["SD", "FIFO"], 4, 1, "simpy")
    assert c["ci_low"] <= c["max_rate"] <= c["ci_high"]
    assert c["policy"] == c["policies"]["ci_low"] in ("SD", "FIFO")
    seeds = replication_seeds(sc.seed + 99, 6)
    ev = Evaluator(tmp_path / "check", ["SD", "FIFO"], seeds, [], 1, "simpy")
    runs = ev.runs([with_overrides(sc, {"feeder.rate": c["ci_low"]})], ["promise"])[0]
    promised = [r["gripping_rate"] for r in runs[c["policy"]]]
    assert sum(promised) / len(promised) >= 80.0
    far = round(1.5 * c["ci_high"], 4)
    best = ev.predict([with_overrides(sc, {"feeder.rate": far})], ["far"])[0]
    assert best.mean["gripping_rate"] < 80.0  # the best rule's mean, so every rule's
