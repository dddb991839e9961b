"""Issue 19, the last report gaps: the single-trace point of a sweep over arrivals says "one
replayed trace: no interval" (no zero-width CI), the capacity report's what-if panel shows
G with its interval at every evaluated flow and rule, and the sweep / size panels show the
total cost with ``--costs`` and "no cost file" without, checked in headless Chromium."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.reports import layout, load_study, render_report
from pnp_twin.reports.answers import NO_INTERVAL, headline
from pnp_twin.reports.capacity import build_capacity_report, rule_runs
from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.capacity import run_capacity
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.stats import t_interval

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "duration": 30.0, "warmup": 5.0, "seed": 3}
CHROMIUM = shutil.which("chromium")
COSTS = "robot_price = 25000\nbelt_price = 8000\nlost_part_cost = 0.05\nhours = 4000\n"


def options() -> Options:
    opts = Options(workers=1, command="pnp-twin test")
    opts.engine = "simpy"
    return opts


@pytest.fixture(scope="module")
def arrivals(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One made-up bursty trace beside Poisson arrivals at its mean rate."""
    root = tmp_path_factory.mktemp("arrivals")
    rng = np.random.default_rng(5)
    times = np.cumsum(rng.gamma(0.6, 0.2, 300))
    rows = "\n".join(
        f"{t:.4f},{y:.3f}" for t, y in zip(times, rng.uniform(0.1, 0.3, 300), strict=True)
    )
    (root / "t.csv").write_text("time,y\n" + rows + "\n")
    over = {**LINE, "feeder.arrival": "trace", "feeder.trace": str(root / "t.csv")}
    over["sweep"] = {"grid": {"feeder.arrival": ["trace", "poisson"]}}
    sc = load_scenario(BASELINE, overrides=over)
    run_sweep(build_plan(sc, policies=["SD"], replications=2), root / "study", options())
    return root / "study"


def test_the_trace_point_of_an_arrival_sweep_says_no_interval(arrivals: Path) -> None:
    study = load_study(arrivals)
    table = layout.kpi_table(study)
    trace_row = next(r for r in table.split("<tr") if ">trace<" in r)
    poisson_row = next(r for r in table.split("<tr") if ">poisson<" in r)
    assert NO_INTERVAL in trace_row and "± 0.0" not in trace_row
    assert NO_INTERVAL not in poisson_row and "±" in poisson_row
    assert f"({NO_INTERVAL})" in headline(study)  # the base line replays the trace
    section = layout.whatif_section(study)
    assert section is not None
    panel = section.items[0]
    assert '"key": "trace|SD"' in panel
    trace_data = re.search(r'\{"key": "trace\|SD"[^}]*\}', panel)
    assert trace_data is not None and '"low": null' in trace_data.group(0)
    assert NO_INTERVAL in trace_data.group(0)
    assert '"nocost": "no cost file"' in panel
    report = arrivals / "report.html"
    report.write_text(render_report(arrivals), encoding="utf-8")
    text = browse(report, [(0, "trace")])
    assert f"({NO_INTERVAL})" in text and text.endswith("no cost file"), text


@pytest.fixture(scope="module")
def capacity(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("capacity") / "cap"
    over = {**LINE, "feeder.rate": 3.0}
    sc = load_scenario(BASELINE, overrides=over)
    run_capacity(sc, folder, 80.0, 0.95, ["SD", "FIFO"], 3, 1, "simpy")
    build_capacity_report(folder)
    return folder


def test_the_capacity_report_has_a_what_if_panel_over_flows_and_rules(capacity: Path) -> None:
    c = json.loads((capacity / "capacity.json").read_text())
    runs = rule_runs(capacity, c)
    assert set(runs) == {p["rate"] for p in c["curve"]}  # every flow, both rules, read back
    assert all(set(r) == {"SD", "FIFO"} for r in runs.values())
    html = (capacity / "report.html").read_text()
    assert 'id="whatif"' in html and "<script src=" not in html


def browse(report: Path, steps: list[tuple[int, str]]) -> str:
    """The what-if panel's text in headless Chromium after choosing each (select, option)."""
    sync_api = pytest.importorskip("playwright.sync_api")
    if CHROMIUM is None:
        pytest.skip("chromium is not installed")
    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=args)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(report.as_uri(), wait_until="load")
            for index, option in steps:
                page.locator("#whatif select").nth(index).select_option(option)
            return page.locator("#whatif output").text_content() or ""
        finally:
            browser.close()


def test_the_capacity_what_if_panel_shows_g_in_a_browser(capacity: Path) -> None:
    c = json.loads((capacity / "capacity.json").read_text())
    point = c["curve"][0]
    other = "FIFO" if point["policy"] == "SD" else "SD"
    g = rule_runs(capacity, c)[point["rate"]][other]
    mean, low, high = t_interval(g, c["confidence_each"])
    text = browse(capacity / "report.html", [(0, f"{point['rate']:g}"), (1, other)])
    level = f"{100 * c['confidence_each']:.4g} %"
    want = f"G = {mean:.1f} % ({level} per rule (Bonferroni) CI {max(low, 0):.1f} to "
    assert text.startswith(want), text
    assert f"{min(high, 100):.1f} %)" in text


def test_a_sweep_with_a_cost_file_shows_the_cost_in_a_browser(tmp_path: Path) -> None:
    (tmp_path / "costs.toml").write_text(COSTS)
    sweep = ["sweep", str(BASELINE), "--set", "robots.count=2", "--set", "feeder.rate=4"]
    sweep += ["--set", "sweep.duration=15", "--set", "sweep.warmup=2", "-p", "SD", "-r", "2"]
    sweep += ["--workers", "1", "--set", "sweep.grid={robots.arm_speed: [2, 3]}"]
    runner = CliRunner()
    costs = ["--costs", str(tmp_path / "costs.toml")]
    priced = runner.invoke(app, [*sweep, "--out", str(tmp_path / "a"), *costs])
    assert priced.exit_code == 0, priced.output
    meta = json.loads((tmp_path / "a" / "meta.json").read_text())
    cost = meta["costs"]["rows"][0]["total_cost"]  # arm speed 2, SD: what the panel opens on
    assert cost > 2 * 25000 + 8000
    assert f"total cost {round(cost):,}" in browse(tmp_path / "a" / "report.html", [(0, "2")])
    bad = [*sweep, "--out", str(tmp_path / "c"), "--costs", str(tmp_path / "x.toml")]
    refused = runner.invoke(app, bad)
    assert refused.exit_code == 2 and "--costs" in refused.stderr
    assert not (tmp_path / "c").exists()
