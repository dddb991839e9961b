"""The report in a real headless Chromium (Debian's /usr/bin/chromium), network blocked:
no console or page errors, and every figure div rendered an SVG."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

from reports import build_report
from tests.study_fixture import make_study

CHROMIUM = Path("/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
SCREENSHOT = Path("/tmp/report_screenshot.png")

if not CHROMIUM.exists():
    if os.environ.get("CI"):
        pytest.fail(f"{CHROMIUM} is missing; CI must install it (apt-get install chromium)")
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

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
    # 3 sweeps + heatmaps + policy comparison + robots + timeline + belt
    assert seen["declared"] == 8
    assert seen["divs"] == 8
    assert seen["rendered"] == 8
    assert shot.stat().st_size > 50_000
    shutil.copyfile(shot, SCREENSHOT)


def test_sizing_report_without_records_renders(size_dir: Path, tmp_path: Path) -> None:
    report = build_report(size_dir, tmp_path / "size.html")
    shot = tmp_path / "size.png"
    seen = open_report(report, shot)
    assert seen["errors"] == []
    # sizing chart + one sweep + policy comparison + robots; no heatmap, no timeline
    assert seen["declared"] == seen["divs"] == seen["rendered"] == 4
    html = report.read_text(encoding="utf-8")
    assert re.search(r"needs \d robots|None of the values tried", html)
    shutil.copyfile(shot, SCREENSHOT.with_name("report_screenshot_size.png"))
