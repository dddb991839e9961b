"""Each report sentence issue #32 found wrong or misleading, corrected; one test each."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from pnp_twin.reports.design import all_table, bonferroni_text, build_design_page
from pnp_twin.reports.html import render
from pnp_twin.reports.record_figures import robot_count
from pnp_twin.reports.text import fmt_bound
from pnp_twin.reports.whatif import whatif_html
from pnp_twin.studies.design import run_design
from pnp_twin.studies.design_text import alternative_text, choice_text
from pnp_twin.twin.loader import load_scenario

LINE = {"robots.count": 2, "feeder.rate": 4.0, "duration": 60.0, "warmup": 10.0, "seed": 5}
COSTS = "robot_price = 20000\nbelt_price = 5000\nlost_part_cost = 0.02\nhours = 2000\n"


@pytest.fixture(scope="module")
def design(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("sentences")
    (root / "costs.toml").write_text(COSTS)
    sc = load_scenario("paper_baseline", LINE)
    return run_design(
        sc, root / "d", 90.0, ["robots.count=2:5"], ["SD"], root / "costs.toml", 0.95, 3, 24
    )


def test_bonferroni_counts_configurations_and_looks(design: dict) -> None:
    text = bonferroni_text(design)
    assert text == "Bonferroni over 4 configurations × 4 looks = 16"
    assert design["confidence_each"] == pytest.approx(1 - 0.05 / 16)
    assert "Bonferroni over 4)" not in render(build_design_page(design))


def test_the_method_names_the_replications_reached_not_the_rounds(design: dict) -> None:
    page = render(build_design_page(design))
    reached = ", ".join(map(str, design["replications_reached"]))
    assert f"configurations ended with {reached} replications" in page
    assert "(rounds" not in page


def test_bounds_never_round_across_the_target() -> None:
    assert fmt_bound(94.99, 95.0) == "94.99"
    assert fmt_bound(95.0, 95.0) == "95.0"
    assert fmt_bound(95.04, 95.0) == "95.0"
    assert fmt_bound(94.96, 95.0) == "94.96"
    assert fmt_bound(80.04, 95.0) == "80.0"
    d = {"target": 95.0, "vary": {}, "rows": [
        {"choice": {"policy": "SD"}, "gripping_rate": 96.0, "ci_low": 94.99, "ci_high": 97.0,
         "replications": 24, "state": "open", "total_cost": 1.0},
    ]}  # fmt: skip
    assert "94.99 to 97.0 %" in all_table(d)


def test_every_configuration_table_shows_the_cost_it_is_sorted_by(design: dict) -> None:
    html = all_table(design)
    assert "Total cost" in html
    costs = [float(x.replace(",", "")) for x in re.findall(r">([\d,]{5,})<", html)]
    assert costs and costs == sorted(costs)


def test_a_field_is_named_with_its_section_and_unit() -> None:
    text = choice_text({"belt.speed": 0.4, "belt.length": 2.4, "policy": "SD"})
    assert text == "belt speed 0.4 m/s, belt length 2.4 m running SD"


def test_the_cheaper_to_buy_option_within_the_noise_is_not_said_to_cost_more() -> None:
    d = {"choice": {"robots.count": 6, "policy": "SD"}, "total_cost": 100_000.0,
         "capital_cost": 80_000.0, "replications": 6, "alternatives": [
        {"choice": {"robots.count": 5, "policy": "SD"}, "total_cost": 104_123.0,
         "capital_cost": 54_000.0, "extra_low": -21_900.0, "extra_high": 30_100.0,
         "replications": 3},
    ]}  # fmt: skip
    text = alternative_text(d)
    assert "for 4,123 more" not in text
    assert "costs the same within the lost parts' noise" in text
    assert "26,000 cheaper to buy" in text


def test_the_same_hardware_is_not_offered_as_an_alternative_for_more() -> None:
    d = {"choice": {"robots.count": 6, "belt.length": 2.0, "policy": "SD"},
         "total_cost": 100.0, "capital_cost": 80.0, "replications": 6, "alternatives": [
        {"choice": {"robots.count": 6, "belt.length": 2.5, "policy": "SD"},
         "total_cost": 152.0, "capital_cost": 80.0, "extra_low": 10.0, "extra_high": 90.0,
         "replications": 6},
    ]}  # fmt: skip
    assert "on the same hardware for 52 more in lost parts" in alternative_text(d)


def test_the_buy_card_names_the_overridden_robot(tmp_path: Path) -> None:
    (tmp_path / "line.toml").write_text(
        "duration = 60.0\nwarmup = 10.0\nseed = 5\n[feeder]\nrate = 4.0\n[robots]\ncount = 3\n"
        "[[robots.overrides]]\nrobot = 2\narm_speed = 1.5\n"
    )
    sc = load_scenario(tmp_path / "line.toml")
    d = run_design(sc, tmp_path / "d", 80.0, ["robots.count=3:4"], ["SD"], None, 0.95, 3, 6)
    page = build_design_page(d)
    buy = page.cards[0][1]
    assert "robot 2 arm speed 1.5 m/s" in buy, buy


def test_a_sparse_what_if_offers_only_the_combinations_run_sorted() -> None:
    rows = [
        {"values": {"robots.count": n, "robots.arm_speed": v}, "policy": "SD", "mean": 90.0,
         "low": 89.0, "high": 91.0, "cost": 1.0}
        for n, v in [(3, 4.804), (2, 5.5), (3, 2.25), (2, 3.1)]
    ]  # fmt: skip
    html = whatif_html(["robots.count", "robots.arm_speed"], rows)
    options = re.findall(r"<option value=\"([^\"]+)\"", html)
    assert options == ["2|3.1|SD", "2|5.5|SD", "3|2.25|SD", "3|4.804|SD"]
    assert html.count('id="whatif"') == 0  # the section holds id="whatif"; the panel its own


def test_the_design_page_has_one_whatif_id(design: dict) -> None:
    assert render(build_design_page(design)).count('id="whatif"') == 1


def test_the_robot_chart_counts_only_the_robots_of_the_line_shown() -> None:
    rows = pd.DataFrame(
        {
            **{f"r{i}_utilisation": [0.5, 0.5] for i in range(1, 5)},
            "r5_utilisation": [None, 0.4],
            "r6_utilisation": [None, 0.3],
        }
    )
    assert robot_count(rows.iloc[:1]) == 4
    assert robot_count(rows.iloc[1:]) == 6


def test_the_what_if_never_rounds_a_bound_across_the_target_in_a_browser(tmp_path: Path) -> None:
    import shutil

    sync_api = pytest.importorskip("playwright.sync_api")
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium is not installed")
    rows = [
        {"values": {"robots.count": 5}, "policy": "SD", "mean": 96.0, "low": 94.99,
         "high": 97.0, "cost": 1.0},
    ]  # fmt: skip
    page_html = f"<html><body>{whatif_html(['robots.count'], rows, target=95.0)}</body></html>"
    (tmp_path / "w.html").write_text(page_html, encoding="utf-8")
    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=args)
        try:
            page = browser.new_page()
            page.goto((tmp_path / "w.html").as_uri(), wait_until="load")
            text = page.locator("output").text_content() or ""
        finally:
            browser.close()
    assert "CI 94.99 to 97.0 %" in text, text
