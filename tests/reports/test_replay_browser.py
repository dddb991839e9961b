"""The replay in a real headless Chromium (network blocked): it plays (the frames change),
the scrubber moves the clock, "next lost part" jumps to one, no console errors; and at three
times the part and tool positions it drew (read back from the page) are those computed from
the run's events and spans (:mod:`reports.replay_data`, itself checked against the twin in
test_replay_data.py)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from pnp_twin.policies import make_policy
from pnp_twin.reports.replay_data import parts_at, replay_data, tools_at
from pnp_twin.reports.run_report import build_run_report
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate

CHROMIUM = Path("/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed (apt-get install chromium)", allow_module_level=True)

sync_api = pytest.importorskip("playwright.sync_api")

DRAWN = "() => window.pnpReplays.map(r => r.lanes.map(l => l.drawn))"


def seek(page: Any, t: float) -> None:
    """Drag the scrubber to ``t`` as a user does (an input event on the range)."""
    page.evaluate(
        "t => { const s = document.querySelector('.rp-scrub'); s.value = t;"
        " s.dispatchEvent(new Event('input')); }",
        t,
    )


def browse(report: Path, script: Any) -> tuple[Any, list[str], list[str]]:
    errors: list[str] = []
    blocked: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})

            def route(r: Any) -> None:
                if r.request.url.startswith("file://"):
                    r.continue_()
                else:
                    blocked.append(r.request.url)
                    r.abort()

            page.route("**/*", route)
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(report.as_uri(), wait_until="load")
            page.wait_for_function("() => window.pnpReplays && window.pnpReplays.length")
            out = script(page)
        finally:
            browser.close()
    return out, errors, blocked


@pytest.fixture(scope="module")
def run_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    scn = load_scenario("two_sided", {"duration": 40.0, "warmup": 10.0})
    result = simulate(scn, make_policy("SD", scn.robots.count), seed=2)
    out = tmp_path_factory.mktemp("replay") / "run.html"
    scenario = scn.model_dump(mode="json")
    build_run_report(result.kpis, result.parts, result.spans, scenario, out)
    data = replay_data(result.parts, result.spans, scenario, 2, None, 60.0, "SD, seed 2")
    return out, data


def test_the_replay_plays_scrubs_and_jumps(run_report: tuple[Path, dict[str, Any]]) -> None:
    report, data = run_report

    def script(page: Any) -> dict[str, Any]:
        got: dict[str, Any] = {"first": page.evaluate(DRAWN)[0][0]}
        got["pixels0"] = page.evaluate("() => document.querySelector('.replay canvas').toDataURL()")
        page.select_option(".rp-speed", "10")
        page.click(".rp-play")
        page.wait_for_timeout(800)
        got["playing"] = page.evaluate(DRAWN)[0][0]
        got["pixels1"] = page.evaluate("() => document.querySelector('.replay canvas').toDataURL()")
        page.click(".rp-play")  # pause
        seek(page, 22.5)
        got["clock"] = page.inner_text(".rp-clock")
        got["scrubbed"] = page.evaluate(DRAWN)[0][0]["t"]
        page.click(".rp-lost")
        got["lost_t"] = page.evaluate("() => window.pnpReplays[0].t")
        got["hilite"] = page.evaluate("() => window.pnpReplays[0].hilite")
        return got

    got, errors, blocked = browse(report, script)
    assert errors == [] and blocked == []
    assert got["first"]["t"] == data["t0"] == 10.0
    assert got["playing"]["t"] > 10.0 + 1.0  # 10x for 0.8 s
    assert got["pixels1"] != got["pixels0"]  # the frames change
    assert got["clock"] == "t = 22.5 s" and got["scrubbed"] == 22.5
    lost = {
        pid: left
        for pid, left, f in zip(
            data["parts"]["id"], data["parts"]["left"], data["parts"]["fate"], strict=True
        )
        if f == 1
    }
    nxt = min((t for t in lost.values() if t > 22.5 + 3.05), default=None)
    if nxt is not None:
        assert got["lost_t"] == pytest.approx(nxt - 3.0)
        assert lost[got["hilite"]] == nxt


def test_what_is_drawn_is_what_the_records_say(run_report: tuple[Path, dict[str, Any]]) -> None:
    report, data = run_report
    times = [11.3, 19.05, 33.7]

    def script(page: Any) -> list[Any]:
        out = []
        for t in times:
            seek(page, t)
            out.append(page.evaluate(DRAWN)[0][0])
        return out

    drawn, errors, _ = browse(report, script)
    assert errors == []
    for t, seen in zip(times, drawn, strict=True):
        assert seen["t"] == pytest.approx(t)
        want_parts = parts_at(data, t)
        assert {int(k) for k in seen["parts"]} == set(want_parts)
        assert len(want_parts) > 5
        for pid, xy in want_parts.items():
            assert seen["parts"][str(pid)] == pytest.approx(list(xy), abs=1e-9)
        for tool, want in zip(seen["tools"], tools_at(data, t), strict=True):
            assert tool == pytest.approx(list(want), abs=1e-9)


def test_the_report_says_which_window_it_replays(run_report: tuple[Path, Any]) -> None:
    html = run_report[0].read_text(encoding="utf-8")
    assert re.search(r"from t = 10 s to 40 s", html)
