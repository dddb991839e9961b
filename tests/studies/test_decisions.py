"""Issue 19, the study side: sizing after a selection among rules, re-targeting a finished
study from its stored runs, the workbook, calibration's noise-aware ranges and turning a
trace scenario into random arrivals at the trace's rate. Lines are made up and tiny."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import openpyxl
import pandas as pd
import pytest

from pnp_twin.studies import Options
from pnp_twin.studies.calibrate import Problem, calibrate
from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.calibrate_fields import apply_values, parse_fit, resolve_path
from pnp_twin.studies.calibrate_output import summary as calibration_summary
from pnp_twin.studies.calibrate_targets import read_targets
from pnp_twin.studies.export import export_xlsx
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.studies.sizing import COUNT, MTBF, analyse, run_size
from pnp_twin.studies.summary import summarise
from pnp_twin.twin.loader import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "feeder.rate": 4.0, "duration": 40.0, "warmup": 5.0, "seed": 3}


def options() -> Options:
    opts = Options(workers=1, command="pnp-twin size test")
    opts.engine = "simpy"
    return opts


def _rows(values: dict[tuple[int, str], list[float]]) -> pd.DataFrame:
    rows = []
    for point, ((n, policy), gs) in enumerate(values.items()):
        for k, g in enumerate(gs):
            rows.append(
                {
                    "point": point // 2,
                    COUNT: n,
                    MTBF: 0.0,
                    "policy": policy,
                    "replication": k,
                    "gripping_rate": g,
                    "throughput": 1.0 * n,
                    "efficiency": 1.0,
                    "utilisation": 1.0,
                    "part_flow": 10.0,
                }
            )
    return pd.DataFrame(rows)


def test_size_holds_its_confidence_after_picking_the_best_rule() -> None:
    # at 2 robots A's own 95 % interval (93 ± 2.48) clears 90, but A was picked as the best
    # of two rules: with both intervals at 97.5 % (Bonferroni) its bound is 89.4, not 90
    df = _rows(
        {
            (2, "A"): [92.0, 93.0, 94.0],
            (2, "B"): [80.0, 81.0, 82.0],
            (3, "A"): [99.0, 99.5, 100.0],
            (3, "B"): [98.0, 98.5, 99.0],
        }
    )
    line = load_scenario("paper_baseline")
    s = analyse(df, summarise(df, [COUNT, MTBF]), [COUNT, MTBF], line, 90.0, 0.95)
    rows = {r[COUNT]: r for r in s["rows"]}
    assert rows[2]["ci_low"] == pytest.approx(93.0 - 6.205 / math.sqrt(3), abs=1e-3)
    assert not rows[2]["reached"] and rows[3]["reached"]
    assert s["answer"] == 3 and s["rule"] == "A"
    assert s["selection"]["rules"] == 2
    assert s["selection"]["confidence_each"] == pytest.approx(0.975)
    assert s["text"].startswith("3 robots running A reach a 90 % gripping rate")


@pytest.fixture(scope="module")
def sized(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("decisions") / "size"
    sc = load_scenario(BASELINE, overrides={**LINE, "sweep": {"grid": {COUNT: [1, 2, 3]}}})
    run_size(sc, folder, 50.0, options(), ["SD", "SPT"], 2)
    return folder


def test_size_again_with_another_target_and_confidence_reuses_every_run(
    sized: Path, tmp_path: Path
) -> None:
    first = json.loads((sized / "meta.json").read_text())
    study = json.loads((sized / "study.json").read_text())
    assert study["analysis"] == {"target": 50.0, "confidence": 0.95}
    assert "target" not in study and study["layout"] == "extend"
    folder = tmp_path / "again"
    import shutil

    shutil.copytree(sized, folder)
    sc = load_scenario(BASELINE, overrides={**LINE, "sweep": {"grid": {COUNT: [1, 2, 3]}}})
    opts = options()
    opts.confidence = 0.9
    _, sizing = run_size(sc, folder, 99.9, opts, ["SD", "SPT"], 2)  # refused before issue 19
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["runs_executed"] == 0 and meta["runs_skipped"] == first["runs"]
    assert sizing["target"] == 99.9 and sizing["confidence"] == 0.9
    assert json.loads((folder / "sizing.json").read_text())["target"] == 99.9
    summary = pd.read_csv(folder / "summary.csv")
    before = pd.read_csv(sized / "summary.csv")
    narrower = summary["gripping_rate_ci_high"] - summary["gripping_rate_ci_low"]
    wider = before["gripping_rate_ci_high"] - before["gripping_rate_ci_low"]
    assert (narrower <= wider + 1e-9).all()  # 90 % intervals from the same runs
    # a simulation setting is still a different study
    with pytest.raises(StudyError, match="holds a different study"):
        run_size(sc, folder, 99.9, options(), ["SD", "SPT"], 2, layout="share")


def test_workbook_keeps_seeds_as_text_labels_decisions_and_has_the_mttr(
    sized: Path, tmp_path: Path
) -> None:
    out = tmp_path / "size.xlsx"
    export_xlsx(sized, out)
    book = openpyxl.load_workbook(out)
    assert "welch" in book.sheetnames
    results = pd.read_excel(out, sheet_name="results", dtype={"seed": str})
    csv = pd.read_csv(sized / "results.csv", dtype={"seed": str})
    assert results["seed"].tolist() == csv["seed"].tolist()  # every digit, not 1.23e+15
    cells = [c.value for c in book["results"][1]]
    seed_cell = book["results"].cell(row=2, column=cells.index("seed") + 1)
    assert seed_cell.data_type == "s"
    assert "rule_NooP (decisions)" in cells and "rule_NooP (parts)" not in cells
    assert "welch_gripping_rate" not in cells  # the per-run list has its own sheet
    assert "robots.mttr (s)" in cells
    mttr = results["robots.mttr (s)"]
    assert set(mttr[results["robots.mtbf (s)"] > 0]) == {30.0}
    assert set(mttr[results["robots.mtbf (s)"] == 0]) == {0.0}
    welch = pd.read_excel(out, sheet_name="welch")
    assert list(welch.columns) == ["run_id", "bin", "gripping_rate (%)"]


def _trace_line(tmp_path: Path, n: int = 400, gap: float = 0.14) -> Path:
    rng = np.random.default_rng(5)
    gaps = rng.gamma(4.0, gap / 4.0, n)
    times = np.cumsum(gaps)
    lines = ["time,y"] + [
        f"{t:.4f},{y:.3f}" for t, y in zip(times, rng.uniform(0.1, 0.3, n), strict=True)
    ]
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    text = BASELINE.read_text()
    text = text.replace('arrival = "poisson"', 'arrival = "trace"\ntrace = "t.csv"')
    text = text.replace("rate = 10.0               # parts/s\n", "")
    path = tmp_path / "traced.toml"
    path.write_text(text)
    return path


def test_set_arrival_on_a_trace_scenario_uses_the_trace_mean_rate(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = _trace_line(tmp_path)
    times = pd.read_csv(tmp_path / "t.csv")["time"].to_numpy()
    gaps = np.diff(times)
    rate, cv = 1 / gaps.mean(), gaps.std(ddof=1) / gaps.mean()
    short = {"duration": 40.0, "warmup": 5.0}
    assert load_scenario(path, short).feeder.arrival == "trace"
    with caplog.at_level(logging.WARNING, logger="pnp_twin"):
        sc = load_scenario(path, {**short, "feeder.arrival": "poisson"})
    assert sc.feeder.arrival == "poisson" and sc.feeder.trace is None
    assert sc.feeder.rate == pytest.approx(rate, rel=1e-5)
    said = [r.getMessage() for r in caplog.records if "replaces the trace" in r.getMessage()]
    assert len(said) == 1 and "t.csv" in said[0] and f"{rate:.4g} parts/s" in said[0]
    normal = load_scenario(path, {**short, "feeder.arrival": "normal"})
    assert normal.feeder.cv == pytest.approx(cv, rel=1e-5)
    assert normal.feeder.rate == pytest.approx(rate, rel=1e-5)
    mine = load_scenario(path, {**short, "feeder.arrival": "poisson", "feeder.rate": 3.0})
    assert mine.feeder.rate == 3.0  # a rate given too wins


def test_calibration_ranges_hold_the_truth_of_a_line_fitted_almost_exactly(
    tmp_path: Path,
) -> None:
    # targets made by the twin itself at a known bin distance, with other seeds than the fit
    short = {"duration": 60.0, "warmup": 10.0}
    sc = load_scenario("two_robot", short)
    true_bin, arms = 0.4, (2.0, 3.0, 4.5)
    where, arm = resolve_path("robots.bin_offset.1"), resolve_path("robots.arm_speed")
    seeds = replication_seeds(sc.seed + 101, 3)
    ev = Evaluator(tmp_path / "truth", ["SPT"], seeds, [], engine="simpy")
    preds = ev.predict(
        [apply_values(sc, {where: true_bin, arm: a}) for a in arms], [str(a) for a in arms]
    )
    csv = tmp_path / "targets.csv"
    body = [f"{a},{p.mean['gripping_rate']!r}" for a, p in zip(arms, preds, strict=True)]
    csv.write_text("robots.arm_speed,gripping_rate\n" + "\n".join(body) + "\n")
    problem = Problem(
        sc,
        read_targets(csv),
        (parse_fit("robots.bin_offset.1=0.1:0.8"),),
        ("SPT",),
        3,
        max_evals=14,
        profile=7,
        pairs=0,
    )
    cal = calibrate(problem, tmp_path / "fit", engine="simpy")
    info = calibration_summary(cal, "pnp-twin calibrate test", tmp_path / "x.toml")
    lo, hi = info["params"][0]["near_optimal"]
    assert lo <= true_bin <= hi, (lo, hi, info["params"][0]["value"])
    noise = info["noise"]
    assert noise["seed_variance"] > 0 and info["near_optimal_margin"] > 1.0


def _tight(mean: float) -> list[float]:
    return [mean - 0.1, mean, mean + 0.1]


def test_size_tests_counts_in_a_fixed_sequence_from_the_largest_down() -> None:
    """Count 2 reaches the target but count 3 misses it: testing every count at the full
    level and keeping the smallest pass would answer 2 with an error that grows with the
    counts tried; the fixed sequence (largest count first, stop at the first miss) answers 4."""
    rows = []
    for point, (n, g) in enumerate({1: 50.0, 2: 95.0, 3: 85.0, 4: 95.0, 5: 95.0}.items()):
        for k, v in enumerate(_tight(g)):
            rows.append(
                {"point": point, COUNT: n, MTBF: 0.0, "policy": "SD", "replication": k,
                 "gripping_rate": v, "throughput": 1.0 * n, "efficiency": 1.0,
                 "utilisation": 1.0, "part_flow": 10.0}
            )  # fmt: skip
    df = pd.DataFrame(rows)
    line = load_scenario("paper_baseline")
    s = analyse(df, summarise(df, [COUNT, MTBF]), [COUNT, MTBF], line, 90.0, 0.95)
    assert {r[COUNT]: r["reached"] for r in s["rows"]}[2]  # reached, yet not the answer
    assert s["answer"] == 4 and s["rule"] == "SD"
    assert s["selection"]["method"] == "fixed-sequence"
    assert "fixed-sequence testing" in s["selection"]["text"]
    assert "from the largest down" in s["selection"]["text"]
    from pnp_twin.reports.text import sizing_text

    assert s["selection"]["text"] in sizing_text(s)  # the report's method line


def test_size_runs_one_fixed_sequence_per_rule_at_the_bonferroni_level() -> None:
    """Rule A reaches at 2 and 3, misses at 4, reaches at 5: its sequence stops at 5. Rule B
    reaches from 3 up: the answer is 3 running B (picking the best rule per count would
    answer 2 running A), and the row at 3 shows B, though A has the higher bound there."""
    df = _rows(
        {
            **{(n, "A"): _tight(g) for n, g in {2: 95.0, 3: 96.0, 4: 85.0, 5: 95.0}.items()},
            **{(n, "B"): _tight(g) for n, g in {2: 80.0, 3: 93.0, 4: 93.0, 5: 93.0}.items()},
        }
    )
    df["point"] = df[COUNT] - 2  # _rows numbers points for rules given in pairs
    line = load_scenario("paper_baseline")
    s = analyse(df, summarise(df, [COUNT, MTBF]), [COUNT, MTBF], line, 90.0, 0.95)
    assert s["answer"] == 3 and s["rule"] == "B"
    assert s["selection"]["method"] == "fixed-sequence + bonferroni"
    assert s["text"].startswith("3 robots running B reach a 90 % gripping rate")
    at_3 = next(r for r in s["rows"] if r[COUNT] == 3)
    assert at_3["policy"] == "B" and at_3["reached"]  # the answer's rule, for the report
    down = s["breakdown"]["n_minus_1"]  # the same rule, one robot fewer
    assert (down["robots"], down["policy"], down["reached"]) == (2, "B", False)
    assert down["ci_low"] == pytest.approx(80.0 - 6.205 * 0.1 / math.sqrt(3), abs=1e-3)
