"""The run report of the new line shapes: robots on both sides or over the belt with a reach
(the belt figure draws each robot's workspace, side, base, reach and bin where
``twin.plan.robot_specs`` puts them) and kinds of part (a per-kind table, the value rate
beside G, the kinds no robot picks named); a line of one kind keeps its report."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import plotly.graph_objects as go
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.reports import record_figures
from pnp_twin.reports.html import render
from pnp_twin.reports.run_report import build_run_page, build_run_report
from pnp_twin.reports.text import fmt_pct
from pnp_twin.twin import simulate
from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.plan import robot_specs
from pnp_twin.twin.scenario import Scenario

SHORT = {"duration": 30, "warmup": 5}


@dataclass
class Built:
    scenario: Scenario
    kpis: dict[str, Any]
    html: str
    belt: go.Figure
    specs: list[RobotSpec]


def build(name: str, folder: Path, overrides: dict[str, Any] | None = None) -> Built:
    """A short run of the shipped scenario ``name``, its report written and read back."""
    scenario = with_overrides(load_scenario(name), {**SHORT, **(overrides or {})})
    result = simulate(scenario, make_policy(scenario.policy, scenario.robots.count))
    data = scenario.model_dump(mode="json")
    out = build_run_report(result.kpis, result.parts, result.spans, data, folder / f"{name}.html")
    page = build_run_page(result.kpis, result.parts, result.spans, data)
    belt = next(i for s in page.sections for i in s.items if getattr(i, "frames", None))
    html = out.read_text(encoding="utf-8")
    assert html == render(page)  # the page looked at below is the one written
    return Built(scenario, dict(result.kpis), html, belt, robot_specs(scenario))


@pytest.fixture(scope="module")
def two_sided(tmp_path_factory: pytest.TempPathFactory) -> Built:
    return build("two_sided", tmp_path_factory.mktemp("shapes"))


@pytest.fixture(scope="module")
def waste(tmp_path_factory: pytest.TempPathFactory) -> Built:
    return build("waste_sorting", tmp_path_factory.mktemp("shapes"))


@pytest.fixture(scope="module")
def baseline(tmp_path_factory: pytest.TempPathFactory) -> Built:
    return build("paper_baseline", tmp_path_factory.mktemp("shapes"))


def shapes(fig: go.Figure) -> dict[str, Any]:
    """The belt figure's shapes by name ("belt", "bin R2", "reach R3", ...)."""
    named = {s.name: s for s in fig.layout.shapes}
    assert len(named) == len(fig.layout.shapes)  # every shape named once
    return named


def section(html: str, sid: str) -> str:
    start = html.index(f'<section id="{sid}">')
    return html[start : html.index("</section>", start)]


@pytest.mark.parametrize("which", ["two_sided", "waste"])
def test_each_robot_is_drawn_on_its_side_where_robot_specs_put_it(
    which: str, request: pytest.FixtureRequest
) -> None:
    built: Built = request.getfixturevalue(which)
    fig, width = built.belt, built.scenario.belt.width
    named = shapes(fig)
    belt = named["belt"]
    assert (belt.x0, belt.x1, belt.y0, belt.y1) == (0, built.scenario.belt.length, 0, width)
    sides = {s.side for s in built.specs}
    assert sides == {"upper", "lower"}  # both shipped lines are worked from both sides
    labels = {a.text: a for a in fig.layout.annotations}
    for spec in built.specs:
        tag = f"R{spec.index + 1}"
        ws, bin_, base = named[f"workspace {tag}"], named[f"bin {tag}"], named[f"base {tag}"]
        assert (ws.x0, ws.x1) == spec.workspace
        bx, by = (bin_.x0 + bin_.x1) / 2, (bin_.y0 + bin_.y1) / 2
        assert (bx, by) == pytest.approx(spec.bin)
        assert (base.xanchor, base.yanchor) == pytest.approx(spec.mount)
        bar = named[f"side {tag}"]
        assert (bar.x0, bar.x1) == spec.workspace and bar.y0 == bar.y1
        if spec.side == "upper":  # above the belt: bin, base and side bar at its upper edge
            assert by > width and base.yanchor > width and bar.y0 == width
        else:  # below the belt
            assert by < 0 and base.yanchor < 0 and bar.y0 == 0
        label = labels[f"<b>{tag}</b> bin"]
        assert label.x == pytest.approx(spec.bin[0])
        assert (label.y > by) if spec.side == "upper" else (label.y < by)
        assert labels[f"<b>{tag}</b>"].y == pytest.approx(spec.mount[1])
    y0, y1 = fig.layout.yaxis.range
    assert y0 < min(s.bin[1] for s in built.specs) and y1 > max(s.bin[1] for s in built.specs)


@pytest.mark.parametrize("which", ["two_sided", "waste"])
def test_a_reach_circle_around_each_base_with_a_reach(
    which: str, request: pytest.FixtureRequest
) -> None:
    built: Built = request.getfixturevalue(which)
    named = shapes(built.belt)
    reaches = {k for k in named if k.startswith("reach ")}
    assert reaches == {f"reach R{s.index + 1}" for s in built.specs if s.reach > 0}
    assert len(reaches) == len(built.specs)
    for spec in built.specs:
        c = named[f"reach R{spec.index + 1}"]
        assert c.type == "circle"
        assert ((c.x0 + c.x1) / 2, (c.y0 + c.y1) / 2) == pytest.approx(spec.mount)
        assert (c.x1 - c.x0) / 2 == pytest.approx(spec.reach)
        assert (c.y1 - c.y0) / 2 == pytest.approx(spec.reach)
    assert built.belt.layout.yaxis.scaleanchor == "x"  # metres alike: the circles are round


def test_no_reach_circle_where_a_robot_has_no_reach(two_sided: Built) -> None:
    data = two_sided.scenario.model_dump(mode="json")
    data["robots"]["overrides"] = [
        {"robot": 2, "side": "lower", "reach": 0.0},
        {"robot": 4, "side": "lower"},
    ]
    spec = record_figures.line_specs(data)
    assert [s.reach for s in spec] == [0.7, 0.0, 0.7, 0.7]
    empty = _no_parts()
    named = shapes(record_figures.belt_figure(empty, data, 5.0, 1.0, 0.5))
    assert sorted(k for k in named if k.startswith("reach ")) == [
        "reach R1",
        "reach R3",
        "reach R4",
    ]
    assert "base R2" in named and named["bin R2"].y1 < 0  # still drawn, on its side
    data["robots"]["reach"] = 0.0
    data["robots"]["overrides"] = [{"robot": 2, "side": "lower"}, {"robot": 4, "side": "lower"}]
    fig = record_figures.belt_figure(empty, data, 5.0, 1.0, 0.5)
    assert not [k for k in shapes(fig) if k.startswith("reach ")]
    assert fig.layout.yaxis.scaleanchor is None  # no circle to keep round


def _no_parts() -> pd.DataFrame:
    """An empty part record: the belt figure's shapes without a part on the belt."""
    cols = ["part", "fed_at", "y", "kind", "outcome", "robot", "decided_at", "left_at"]
    frame = pd.DataFrame({c: pd.Series(dtype=float) for c in cols})
    frame["robot"] = frame["robot"].astype("Int64")
    return frame


def test_the_one_sided_line_is_drawn_as_before(baseline: Built) -> None:
    named = shapes(baseline.belt)
    n = baseline.scenario.robots.count
    assert [s.type for s in baseline.belt.layout.shapes].count("rect") == 1 + n + n
    assert not [k for k in named if k.split()[0] in ("side", "base", "reach")]
    for spec in baseline.specs:  # bins from robot_specs, above the belt
        b = named[f"bin R{spec.index + 1}"]
        assert ((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2) == pytest.approx(spec.bin)
        assert spec.bin[1] > baseline.scenario.belt.width
    assert [t.name for t in baseline.belt.data] == ["to be picked", "claimed", "will be missed"]
    assert baseline.belt.layout.yaxis.range[0] == -0.05
    assert baseline.belt.layout.yaxis.scaleanchor is None


def kind_table_rows(html: str) -> dict[str, list[str]]:
    """The per-kind table's body rows: kind name -> the cells' text."""
    body = section(html, "kinds").split("<tbody>", 1)[1].split("</tbody>", 1)[0]
    rows = {}
    for row in re.findall(r"<tr>(.*?)</tr>", body):
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row)
        rows[cells[0].replace(" (not targeted)", "")] = cells
    return rows


def test_the_kinds_table_holds_each_kinds_kpis(waste: Built) -> None:
    kinds = waste.kpis["kinds"]
    rows = kind_table_rows(waste.html)
    assert list(rows) == list(kinds) == ["PET", "can", "residual"]
    for name, k in kinds.items():
        cells = rows[name]
        assert cells[1] == f"{k['value']:g}"
        assert cells[2:6] == [
            str(k["parts_presented"]),
            str(k["parts_picked"]),
            str(k["parts_lost"]),
            str(k["parts_passed_by_design"]),
        ]
        g = k["gripping_rate"]
        assert cells[6] == (fmt_pct(g) if math.isfinite(g) else "–")
        worth = k["value_presented"]
        share = fmt_pct(100 * k["value_picked"] / worth) if worth > 0 else "–"
        assert cells[7] == share
    assert rows["residual"][0] == "residual (not targeted)" and rows["residual"][6] == "–"
    assert kinds["residual"]["parts_passed_by_design"] > 0
    assert int(rows["residual"][5]) == waste.kpis["parts_passed_by_design"]
    assert int(rows["PET"][2]) + int(rows["can"][2]) == waste.kpis["parts_presented"]


def test_the_value_rate_stands_beside_g_and_the_untargeted_kinds_are_named(
    waste: Built,
) -> None:
    html, kpis = waste.html, waste.kpis
    cards = re.findall(r'<div class="k">(.*?)</div><div class="v">(.*?)</div>', html)
    assert cards[:2] == [
        ("Gripping rate", fmt_pct(kpis["gripping_rate"])),
        ("Value rate", fmt_pct(kpis["value_rate"])),
    ]
    n = kpis["kinds"]["residual"]["parts_passed_by_design"]
    said = f"No robot picks residual ({n} parts): it passes on to the end of the belt by design"
    assert said in section(html, "kinds")
    assert "left out of the gripping rate G" in section(html, "kinds")
    answer = section(html, "answer")
    assert f"Value rate {fmt_pct(kpis['value_rate'])}" in answer
    assert f"{kpis['parts_passed_by_design']} parts of kinds no robot picks" in answer
    facts = section(html, "kpis")
    assert f"<th>Value rate</th><td>{fmt_pct(kpis['value_rate'], 2)}" in facts


def test_the_belt_shows_untargeted_parts_as_passed_on_by_design(waste: Built) -> None:
    names = [t.name for t in waste.belt.data]
    assert names == ["to be picked", "claimed", "will be missed", "passed on by design"]
    shown = [t for f in waste.belt.frames for t in f.data if t.name == "passed on by design"]
    assert {row[2] for t in shown for row in t.customdata} == {"residual"}  # only that kind
    missed = [t for f in waste.belt.frames for t in f.data if t.name == "will be missed"]
    assert "residual" not in {row[2] for t in missed for row in t.customdata}


def test_the_settings_table_shows_overridden_sides_and_kinds(waste: Built) -> None:
    table = section(waste.html, "settings")
    assert "Side</th>" in table and "Kinds</th>" in table  # sides alternate, kinds overridden
    assert "Reach (m)</th>" not in table  # the same for every robot: no column
    assert table.count(">lower</td>") == 3 and table.count(">upper</td>") == 3  # alternate
    assert table.count("<b>PET</b> ●") == 2  # robots 5 and 6
    assert table.count(">PET, can</td>") == 4  # robots 1 to 4: the shared kinds


def test_a_line_of_one_kind_has_no_kinds_table(baseline: Built) -> None:
    html = baseline.html
    assert "kinds" not in baseline.kpis
    assert '<section id="kinds">' not in html and "Kinds of part" not in html
    assert "Value rate" not in html and "by design" not in html
    assert "Side</th>" not in html and "Reach (m)</th>" not in html
    cards = re.findall(r'<div class="k">(.*?)</div>', html)
    assert cards == ["Gripping rate", "Throughput", "Robots", "Simulated"]


def test_an_outfeed_line_reports_its_fill_rate_and_held_parts(tmp_path: Path) -> None:
    from pnp_twin.policies import make_policy
    from pnp_twin.reports.run_report import build_run_report
    from pnp_twin.twin import simulate

    sc = with_overrides(load_scenario("tray_loading_counterflow"), {"duration": 60, "warmup": 5})
    result = simulate(sc, make_policy("SPT", sc.robots.count))
    k = result.kpis
    out = build_run_report(
        k, result.parts, result.spans, sc.model_dump(mode="json"), tmp_path / "r.html"
    )
    html = out.read_text()
    assert "Fill rate (containers that left full)" in html
    assert f"{k['containers_full']} of {k['containers']} containers" in html
    assert f"{k['parts_held']} ({k['hold_time']:.1f} s in all" in html
    cards = re.findall(r'<div class="k">(.*?)</div>', html)
    assert cards[:2] == ["Gripping rate", "Fill rate"]
