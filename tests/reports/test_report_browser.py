"""The report in a real headless Chromium (Debian's /usr/bin/chromium), network blocked:
no console or page errors, every figure div rendered an SVG, the belt animation plays when
its Play button is clicked, and a printed PDF (what a browser's Save as PDF makes) keeps
every table row. CI installs chromium and poppler-utils (pdftotext) for these tests; there
(strict mode, see tests/conftest.py) a missing one fails the tests instead of skipping them."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from pnp_twin.reports import build_report
from tests.study_fixture import make_study

CHROMIUM = Path("/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
SCREENSHOT = Path("/tmp/report_screenshot.png")
PDFTOTEXT = shutil.which("pdftotext")

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed (apt-get install chromium)", allow_module_level=True)

sync_api = pytest.importorskip("playwright.sync_api")


@pytest.fixture(scope="session")
def sweep_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    grid = {"robots.arm_speed": [2, 4], "feeder.rate": [10, 15], "belt.speed": [0.6, 1.0]}
    return make_study(tmp_path_factory.mktemp("browser") / "sweep", grid=grid)


@pytest.fixture(scope="session")
def size_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("browser") / "size"
    return make_study(folder, grid={"robots.count": [2, 3, 4]}, kind="size", records=False)


def open_report(report: Path, screenshot: Path) -> dict[str, object]:
    """Load ``report`` from file:// with every other request aborted; what the page did."""
    errors: list[str] = []
    blocked: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})

            def route(r: sync_api.Route) -> None:
                if r.request.url.startswith("file://"):
                    r.continue_()
                else:
                    blocked.append(r.request.url)
                    r.abort()

            page.route("**/*", route)
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(report.as_uri(), wait_until="load")
            page.wait_for_function(
                "() => [...document.querySelectorAll('.plotly-graph-div')]"
                ".every(d => d.querySelector('.main-svg'))",
                timeout=30_000,
            )
            divs = page.locator(".plotly-graph-div").count()
            rendered = page.locator(".plotly-graph-div .main-svg").evaluate_all(
                "els => new Set(els.map(e => e.closest('.plotly-graph-div').id)).size"
            )
            declared = int(
                page.locator('meta[name="pnp-twin-figures"]').get_attribute("content") or -1
            )
            page.screenshot(path=str(screenshot), full_page=True)
        finally:
            browser.close()
    return {
        "errors": errors,
        "blocked": blocked,
        "divs": divs,
        "rendered": rendered,
        "declared": declared,
    }


def test_sweep_report_renders_offline(sweep_dir: Path, tmp_path: Path) -> None:
    report = build_report(sweep_dir)
    shot = tmp_path / "sweep.png"
    seen = open_report(report, shot)
    assert seen["errors"] == []
    assert seen["blocked"] == []  # nothing on the page reaches for the network
    # 3 sweeps + heatmaps + policy comparison + robots + timeline + belt + warm-up
    assert seen["declared"] == 9
    assert seen["divs"] == 9
    assert seen["rendered"] == 9
    assert shot.stat().st_size > 50_000
    shutil.copyfile(shot, SCREENSHOT)


def test_sizing_report_without_records_renders(size_dir: Path, tmp_path: Path) -> None:
    report = build_report(size_dir, tmp_path / "size.html")
    shot = tmp_path / "size.png"
    seen = open_report(report, shot)
    assert seen["errors"] == []
    # sizing chart + layout + count and MTBF sweeps + heatmap + policy comparison + robots
    # + warm-up; no timeline or belt without records
    assert seen["declared"] == seen["divs"] == seen["rendered"] == 8
    html = report.read_text(encoding="utf-8")
    assert re.search(r"\d robots running \S+ reach G ≥ 90 %|No robot count tried reaches", html)
    shutil.copyfile(shot, SCREENSHOT.with_name("report_screenshot_size.png"))


@pytest.fixture(scope="session")
def mix_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """25 mixes (5 rules on 2 robots): tables longer than a screen's scroll box."""
    folder = tmp_path_factory.mktemp("browser") / "mix"
    rules = ("FIFO", "LIFO", "SPT", "SD", "LD")
    line = {"robots.count": 2, "feeder.rate": 5.0}
    return make_study(folder, policies=rules, kind="mix", duration=30.0, warmup=5.0, base=line)


def print_pdf(report: Path, pdf: Path) -> str:
    """Print ``report`` as Chromium's Save as PDF does; the PDF's text, laid out."""
    subprocess.run(
        [
            str(CHROMIUM),
            *ARGS,
            "--no-pdf-header-footer",
            "--virtual-time-budget=10000",
            f"--print-to-pdf={pdf}",
            report.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=180,
    )
    out = subprocess.run(
        [str(PDFTOTEXT), "-layout", str(pdf), "-"], check=True, capture_output=True, text=True
    )
    return out.stdout


@pytest.mark.skipif(PDFTOTEXT is None, reason="pdftotext (poppler-utils) is not installed")
def test_a_printed_report_keeps_every_table_row(mix_dir: Path, tmp_path: Path) -> None:
    # a scroll box of 560 px showed about 15 rows and printed only those (issue 10)
    report = build_report(mix_dir)
    text = print_pdf(report, tmp_path / "mix.pdf")
    rule = r"(FIFO|LIFO|SPT|SD|LD)"
    ranked = re.findall(rf"^\s*(\d+)\s+{rule}\s+{rule}\s+\d", text, flags=re.M)
    assert sorted(int(r[0]) for r in ranked) == list(range(1, 26))  # the ranked table
    kpis = text[text.rindex("KPI summary") :]
    kpi_rows = re.findall(rf"{rule},{rule}( ★)?\s+\d+\.\d %", kpis)
    assert len(kpi_rows) == 25  # the KPI table, one row per mix


def test_the_belt_animation_plays_in_a_browser(sweep_dir: Path) -> None:
    report = build_report(sweep_dir)
    label = (
        "() => [...document.querySelectorAll('.slider-container text')]"
        ".map(t => t.textContent).find(t => t.startsWith('t ='))"
    )
    xs = (
        "() => { const g = [...document.querySelectorAll('.plotly-graph-div')]"
        ".find(d => d.layout.sliders && d.layout.sliders.length);"
        " return [...g.querySelectorAll('.scatterlayer path.point')]"
        ".map(m => m.getAttribute('transform')); }"
    )
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.goto(report.as_uri(), wait_until="load")
            page.wait_for_function(label, timeout=30_000)
            before, parts_before = page.evaluate(label), page.evaluate(xs)
            play = page.locator(".updatemenu-button", has_text="Play").first
            play.scroll_into_view_if_needed()
            play.click()
            page.wait_for_timeout(2000)
            after, parts_after = page.evaluate(label), page.evaluate(xs)
            slider_steps = page.evaluate(
                "() => [...document.querySelectorAll('.plotly-graph-div')]"
                ".find(d => d.layout.sliders && d.layout.sliders.length).layout.sliders[0]"
                ".steps.length"
            )
        finally:
            browser.close()
    assert before == "t = 10.0 s"
    t = float(re.search(r"t = ([\d.]+) s", after).group(1))
    assert t > 10.0, after  # the clock moved: the frames play
    assert parts_before and parts_after != parts_before  # and the parts moved with it
    assert slider_steps == 251  # a window of 50 s (a minute, cut at the run's end) at 0.2 s


def test_run_report_renders_offline(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from pnp_twin.cli import app

    report = tmp_path / "run.html"
    args = ["run", "paper_baseline", "--set", "duration=60", "--set", "warmup=10"]
    result = CliRunner().invoke(app, [*args, "--report", str(report)])
    assert result.exit_code == 0, result.stderr
    seen = open_report(report, tmp_path / "run.png")
    assert seen["errors"] == [] and seen["blocked"] == []
    # robots + timeline + belt + warm-up
    assert seen["declared"] == seen["divs"] == seen["rendered"] == 4
    html = report.read_text(encoding="utf-8")
    assert '<section id="answer">' in html and "With SD the line grips" in html
    shutil.copyfile(tmp_path / "run.png", SCREENSHOT.with_name("report_screenshot_run.png"))
