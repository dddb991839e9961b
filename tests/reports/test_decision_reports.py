"""Issue 19, the report side: every sentence and chart a plant engineer reads is right on
lines made up for the test (the best rule at the base line and its paired margin, a
trace's real rate and its missing interval, MTBF charts where no breakdowns is infinity, the
sizing answer's rule and promise, the run report, the rule-mix findings)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import plotly.graph_objects as go
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.reports import figures, layout, load_study, render_report
from pnp_twin.reports.answers import headline
from pnp_twin.reports.run_report import build_run_page, run_headline
from pnp_twin.reports.text import key_findings
from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.folder import build_tables, write_tables
from pnp_twin.studies.rulemix import run_mix
from pnp_twin.studies.sizing import COUNT, run_size
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "feeder.rate": 4.0, "duration": 40.0, "warmup": 5.0, "seed": 3}


def options() -> Options:
    opts = Options(workers=1, command="pnp-twin test")
    opts.engine = "simpy"
    return opts


def sweep(folder: Path, grid: dict, policies: list[str], reps: int = 2, **base) -> Path:
    sc = load_scenario(BASELINE, overrides={**LINE, **base, "sweep": {"grid": grid}})
    run_sweep(build_plan(sc, policies=policies, replications=reps), folder, options())
    return folder


def test_sweep_answer_names_the_best_rule_at_the_base_line_with_its_margin(
    tmp_path: Path,
) -> None:
    # A wins at arm speeds 2 and 4, B at 3 (the middle of the grid, where the answer looks);
    # before issue 19 the answer named A there, "-0.00 points" behind itself
    g = {
        (2.0, "A"): [80, 81, 82],
        (2.0, "B"): [70, 71, 72],
        (3.0, "A"): [85, 86, 87],
        (3.0, "B"): [86, 88, 90],  # B - A = 1, 2, 3: 2 points, paired CI 2 ± 2.48
        (4.0, "A"): [95, 95, 96],
        (4.0, "B"): [90, 91, 92],
    }
    rows = []
    for (arm, policy), values in g.items():
        for k, v in enumerate(values):
            rows.append(
                {
                    "run_id": f"p{arm}-{policy}-{k}",
                    "point": [2.0, 3.0, 4.0].index(arm),
                    "robots.arm_speed": arm,
                    "policy": policy,
                    "replication": k,
                    "seed": 11 + k,
                    "gripping_rate": float(v),
                    "throughput": v / 10,
                    "efficiency": v / 100,
                    "utilisation": 0.5,
                    "wall_time": 0.1,
                }
            )
    tables = build_tables(rows, ["robots.arm_speed"])
    write_tables(tmp_path, tables)
    meta = {"kind": "sweep", "grid": {"robots.arm_speed": [2.0, 3.0, 4.0]}, "policies": ["A", "B"]}
    (tmp_path / "meta.json").write_text(json.dumps(meta))
    study = load_study(tmp_path)
    text = headline(study)
    assert text.startswith("B is the best policy at the middle of the grid (arm speed 3 m/s)")
    assert "but it cannot be told apart from A (+2.00 points, paired 95 % CI -0.48 to 4.48)" in text
    assert "A is best at the most grid points (2 of 3 grid points)" in text
    assert "-0.00" not in text


@pytest.fixture(scope="module")
def traced(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A made-up trace at about 7.1 parts/s on a two-robot line; the scenario's unused
    feeder.rate stays at 10."""
    root = tmp_path_factory.mktemp("trace")
    rng = np.random.default_rng(2)
    times = np.cumsum(rng.gamma(2.0, 0.07, 500))
    body = "\n".join(
        f"{t:.4f},{y:.3f}" for t, y in zip(times, rng.uniform(0.1, 0.3, 500), strict=True)
    )
    trace = root / "t.csv"
    trace.write_text("time,y\n" + body + "\n")
    base = {"feeder.arrival": "trace", "feeder.trace": str(trace), "feeder.rate": 10.0}
    return sweep(root / "study", {"robots.arm_speed": [2.0, 3.0]}, ["SD", "FIFO"], **base)


def test_a_replayed_trace_states_its_real_rate_and_no_interval(traced: Path) -> None:
    study = load_study(traced)
    meta = json.loads((traced / "meta.json").read_text())
    rate = meta["trace"]["mean_rate"]
    assert 6.5 < rate < 7.8
    facts = layout.facts(study)
    base = re.search(r"<th>Base line</th><td>(.*?)</td>", facts)
    assert base is not None
    assert f"{rate:.3g} parts/s mean of the replayed trace t.csv" in base.group(1)
    assert "10 parts/s" not in base.group(1)
    text = headline(study)
    assert "one replayed trace: no interval" in text and "95 % CI" not in text
    html = render_report(traced)
    table = html[html.index('id="kpis"') :]
    assert "± 0.0" not in table


@pytest.fixture(scope="module")
def failures(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("mtbf") / "study"
    grid = {"robots.mtbf": [0.0, 20.0, 60.0]}
    return sweep(folder, grid, ["SD"], **{"robots.mttr": 5.0, "feeder.rate": 6.0})


def test_no_breakdowns_is_drawn_as_infinite_mtbf_not_zero(failures: Path) -> None:
    study = load_study(failures)
    fig = figures.sweep_figure(study.summary, "robots.mtbf", {}, study.policies)
    line = next(t for t in fig.data if t.mode == "lines+markers")
    assert list(line.x) == ["20", "60", "none (∞)"]
    assert fig.layout.xaxis.type == "category"
    assert list(fig.layout.xaxis.categoryarray) == ["20", "60", "none (∞)"]
    said = [s for s in key_findings(study) if s.startswith("Mean time between failures")]
    assert said and said[0].startswith("Mean time between failures from 20 s to no breakdowns")


@pytest.fixture(scope="module")
def sized(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("size") / "study"
    sc = load_scenario(BASELINE, overrides={**LINE, "sweep": {"grid": {COUNT: [1, 2, 3, 4]}}})
    run_size(sc, folder, 50.0, options(), ["SD", "SPT"], 4)
    return folder


def test_sizing_report_names_the_rule_promises_the_bound_and_shows_the_mttr(
    sized: Path,
) -> None:
    sizing = json.loads((sized / "sizing.json").read_text())
    assert sizing["answer"] is not None, sizing["text"]
    study = load_study(sized)
    text = headline(study)
    assert f"robots running {sizing['rule']} reach G ≥ 50 %" in text
    row = next(r for r in sizing["rows"] if r[COUNT] == sizing["answer"] and r["robots.mtbf"] == 0)
    cards = layout.cards(study)
    assert cards[0] == (
        "Buy",
        f"{sizing['answer']} robots",
        f"running {sizing['rule']} · for G ≥ 50.0 %",
    )
    assert cards[1][0] == "Promise" and cards[1][1] == f"G ≥ {row['ci_low']:.1f} %"
    assert all(c[0] != "Best gripping rate" for c in cards)
    assert cards[2][0] == "With breakdowns" and "MTTR 30 s (assumed)" in cards[2][2]
    html = render_report(sized)
    answer = html[html.index('id="answer"') : html.index("</section>")]
    assert "MTBF 600 s, MTTR 30 s (assumed: the scenario sets no breakdowns)" in answer
    assert "Bonferroni" in answer


def test_run_report_does_not_repeat_g_and_tables_the_overrides() -> None:
    sc = load_scenario(
        BASELINE,
        overrides={
            **LINE,
            "robots.overrides": [{"robot": 2, "arm_speed": 5.0, "mtbf": 30.0, "mttr": 4.0}],
        },
    )
    result = simulate(sc, make_policy("SD", 2), engine="simpy")
    text = run_headline(result.kpis)
    assert "efficiency" not in text
    assert text.count(f"{result.kpis['gripping_rate']:.1f} %") == 1
    page = build_run_page(result.kpis, result.parts, result.spans, sc.model_dump(mode="json"))
    settings = next(s for s in page.sections if s.id == "settings")
    table = settings.items[0]
    assert "Arm speed (m/s)" in table and "<b>5</b> ●" in table and "<b>30</b> ●" in table


def test_mix_findings_are_a_few_sentences_with_the_gap_the_right_way_round(
    tmp_path: Path,
) -> None:
    sc = load_scenario(BASELINE, overrides=LINE)
    run_mix(sc, tmp_path / "mix", options(), ["FIFO", "SPT", "SD"], 3)
    study = load_study(tmp_path / "mix")
    found = key_findings(study)
    assert 2 <= len(found) <= 6
    assert not any(len(re.findall(r"[A-Z]+,[A-Z]+", s)) > 2 for s in found)  # no inline list
    assert found[0].startswith(f"9 mixes evaluated; the best, {study.mix['ranked'][0]['mix']}")
    margin = study.mix["margin"]
    runner = next(s for s in found if s.startswith("The runner-up"))
    assert f"is {margin['diff_mean']:.2f} points behind the best" in runner
    assert margin["diff_mean"] >= 0


def calibration_info() -> dict:
    """A calibration.json as `pnp-twin calibrate` writes it, made up: one varied field, two
    fitted parameters, one of them two fields fitted as one."""
    names = ["robots.bin_offset.1", "robots.pick_time,robots.place_time"]
    points = [
        {
            "point": i + 1,
            "robots.arm_speed": a,
            "kpi": "gripping_rate",
            "target": 80.0 + 5 * i,
            "predicted": 80.5 + 5 * i,
            "ci_low": 79.0 + 5 * i,
            "ci_high": 82.0 + 5 * i,
            "residual": 0.5,
            "weight": 1.0,
            "policy": "SPT",
        }
        for i, a in enumerate((2.0, 3.0, 4.5))
    ]
    curves = [
        {
            "field": "robots.arm_speed",
            "value": a,
            "kpi": "gripping_rate",
            "predicted": 78 + 5 * a,
            "ci_low": 77 + 5 * a,
            "ci_high": 79 + 5 * a,
        }
        for a in (2.0, 3.0, 4.0, 5.0)
    ]
    profiles = [
        {"param": n, "value": v, "param_2": "", "value_2": None, "objective": (v - c) ** 2 * 400}
        for n, c in zip(names, (0.4, 0.06), strict=True)
        for v in (c - 0.1, c, c + 0.1)
    ]
    params = [
        {"name": n, "low": 0.0, "high": 0.8, "start": 0.2, "value": c, "near_optimal": [c, c]}
        for n, c in zip(names, (0.4, 0.06), strict=True)
    ]
    return {
        "params": params,
        "objective": 0.75,
        "near_optimal_margin": 12.5,
        "points": points,
        "curves": curves,
        "profiles": profiles,
        "varied": ["robots.arm_speed"],
        "kpis": ["gripping_rate"],
    }


def test_calibration_figures_have_units_whole_labels_and_the_noise_margin() -> None:
    from pnp_twin.reports import calibration

    info = calibration_info()
    points = calibration.points_figure(info, "gripping_rate")
    assert points.layout.yaxis.title.text == "Gripping rate (%)"
    assert list(points.data[0].x)[0] == "1: arm speed 2.0 m/s"
    curve = calibration.curve_figure(info, "robots.arm_speed", "gripping_rate")
    assert curve.layout.xaxis.title.text == "Arm speed (m/s)"
    assert curve.layout.yaxis.title.text == "Gripping rate (%)"
    prof = calibration.profile_figure(info)
    titles = [a.text for a in prof.layout.annotations]
    assert "Bin offset [1] (m)" in titles
    assert "Pick time<br>= Place time (s)" in titles  # two fields fitted as one, not cut
    assert prof.layout.xaxis.title.text == "value (m)"
    assert prof.layout.xaxis2.title.text == "value (s)"
    lines = [s.y0 for s in prof.layout.shapes if s.line.dash == "dash"]
    assert lines and all(y == pytest.approx(0.75 + 12.5) for y in lines)
    assert "best + 12.5" in prof.layout.title.text


def test_a_long_caption_wraps_instead_of_being_cut() -> None:
    from pnp_twin.reports.style import CAPTION_WIDTH, style, wrap_caption

    caption = "objective over both, the other parameters at the fit; a long diagonal valley: "
    caption += "the data cannot fit both · more words to pass the width of a printed page"
    lines = wrap_caption(caption)
    assert len(lines) >= 2 and all(len(x) <= CAPTION_WIDTH for x in lines)
    assert " ".join(lines).replace("  ", " ").split() == caption.split()
    fig = style(go.Figure(), "Title", caption)
    assert fig.layout.title.text.count("<br>") == len(lines)
    assert fig.layout.margin.t >= 60 + 18 * len(lines)


CHROMIUM = shutil.which("chromium")
PDFTOTEXT = shutil.which("pdftotext")


@pytest.mark.skipif(
    CHROMIUM is None or PDFTOTEXT is None, reason="chromium and pdftotext (poppler) needed"
)
def test_a_printed_calibration_report_keeps_whole_labels_units_and_captions(
    tmp_path: Path,
) -> None:
    from pnp_twin.reports.calibration import build_calibration_report

    info = calibration_info()
    info.update(
        command="pnp-twin calibrate line.toml",
        date="2026-12-01 10:00 UTC",
        scenario="made_up",
        scenario_file="x/scenario.toml",
        targets_file="t.csv",
        policies=["SPT"],
        replications=3,
        duration=60.0,
        warmup=10.0,
        optimiser="Nelder-Mead",
        evaluations=10,
        simulated_points=30,
        replayed_points=0,
        wall_time=5.0,
    )
    (tmp_path / "calibration.json").write_text(json.dumps(info))
    report = build_calibration_report(tmp_path)
    pdf = tmp_path / "cal.pdf"
    subprocess.run(
        [
            str(CHROMIUM),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--no-pdf-header-footer",
            "--virtual-time-budget=10000",
            f"--print-to-pdf={pdf}",
            report.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=180,
    )
    text = subprocess.run(
        [str(PDFTOTEXT), "-layout", str(pdf), "-"], check=True, capture_output=True, text=True
    ).stdout
    flat = " ".join(text.split())
    for label in ("Gripping rate (%)", "Arm speed (m/s)", "Bin offset [1] (m)", "value (s)"):
        assert label in flat, label
    assert "dashed: best + 12.5 (95 %, residual and seed noise)" in flat  # the whole caption
    assert "robots.arm_speed" not in flat.lower()  # labels in words, not dotted paths


def test_the_what_if_panel_shows_the_stored_g_in_a_browser(failures: Path) -> None:
    sync_api = pytest.importorskip("playwright.sync_api")
    if CHROMIUM is None:
        pytest.skip("chromium is not installed")
    html = render_report(failures)
    assert 'id="whatif"' in html and "<script src=" not in html
    report = failures / "report.html"
    report.write_text(html, encoding="utf-8")
    summary = load_study(failures).summary
    row = summary[summary["robots.mtbf"] == 20.0].iloc[0]
    want = (
        f"G = {row['gripping_rate_mean']:.1f} % (95 % CI {row['gripping_rate_ci_low']:.1f} "
        f"to {row['gripping_rate_ci_high']:.1f} %) · no cost file"  # sweep without --costs
    )
    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=args)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(report.as_uri(), wait_until="load")
            out = page.locator("#whatif output")
            first = out.text_content()
            assert first is not None and first.startswith("G = ")
            page.locator("#whatif select").first.select_option("20")
            assert out.text_content() == want
        finally:
            browser.close()


def test_a_trace_beside_random_arrivals_at_its_mean_rate_says_what_bursts_cost(
    traced: Path, tmp_path: Path
) -> None:
    trace = json.loads((traced / "meta.json").read_text())["scenario"]["feeder"]["trace"]
    base = {"feeder.arrival": "trace", "feeder.trace": trace, "feeder.rate": 10.0}
    grid = {"feeder.arrival": ["trace", "poisson", "normal"]}
    folder = sweep(tmp_path / "bursts", grid, ["SD"], **base)
    study = load_study(folder)
    results = study.results
    assert results is not None
    rate = json.loads((traced / "meta.json").read_text())["trace"]["mean_rate"]
    flows = results.groupby("feeder.arrival")["part_flow"].mean()
    assert flows["poisson"] == pytest.approx(rate, rel=0.15)  # the trace's rate, not 10
    g = study.best.set_index("feeder.arrival")["gripping_rate_mean"]
    said = next(s for s in key_findings(study) if s.startswith("Bursts cost"))
    assert said.startswith(f"Bursts cost {g['poisson'] - g['trace']:.1f} points")
    assert not layout.one_trace(study.meta)  # random arrivals do vary: not one sample
    assert "(one replayed trace: no interval)" in headline(study)  # the trace point has none
