"""Reports from study folders: figures from tables, sentences, and the self-contained page."""

from __future__ import annotations

import json
import re
import shutil
from html import escape as html_escape
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from plotly.offline import get_plotlyjs

from pnp_twin.reports import (
    ReportError,
    build_report,
    figures,
    layout,
    load_study,
    record_figures,
    render_report,
    welch,
)
from pnp_twin.reports.answers import headline, mix_headline, size_headline
from pnp_twin.reports.text import fmt_pct, fmt_pm, key_findings, reference_point, sizing_text
from tests.study_fixture import make_study


@pytest.fixture(scope="session")
def sweep3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One parameter with three values, two policies, two replications, records."""
    folder = tmp_path_factory.mktemp("reports") / "sweep3"
    return make_study(folder, grid={"robots.arm_speed": [2, 3, 4]}, policies=("SD", "FIFO"))


@pytest.fixture(scope="session")
def grid3d(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's layout in small: arm speed x part flow x belt speed, two policies."""
    folder = tmp_path_factory.mktemp("reports") / "grid3d"
    grid = {"robots.arm_speed": [2, 4], "feeder.rate": [10, 15], "belt.speed": [0.6, 1.0]}
    return make_study(folder, grid=grid, policies=("SD", "FIFO"))


@pytest.fixture(scope="session")
def sizing(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A sizing study of 2 to 4 robots, a target the simulation reaches at some count."""
    folder = tmp_path_factory.mktemp("reports") / "size"
    return make_study(
        folder,
        grid={"robots.count": [2, 3, 4]},
        policies=("SD",),
        replications=3,
        kind="size",
        target=45.0,
    )


@pytest.fixture(scope="session")
def mix2(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An exhaustive rule-mix search: two rules on a two-robot line, three replications."""
    folder = tmp_path_factory.mktemp("reports") / "mix"
    line = {"robots.count": 2, "feeder.rate": 5.0}
    return make_study(folder, policies=("FIFO", "SPT"), kind="mix", replications=3, base=line)


def test_sweep_figure_has_one_band_per_policy_and_every_value(sweep3: Path) -> None:
    study = load_study(sweep3)
    fig = figures.sweep_figure(study.summary, "robots.arm_speed", {}, study.policies)
    bands = [t for t in fig.data if t.fill == "toself"]
    lines = [t for t in fig.data if t.mode == "lines+markers"]
    assert sorted(t.legendgroup for t in bands) == ["FIFO", "SD"]
    assert [t.name for t in lines] == ["SD", "FIFO"]
    for line in lines:
        assert list(line.x) == [2, 3, 4]
        means = study.summary[study.summary["policy"] == line.name].sort_values("robots.arm_speed")[
            "gripping_rate_mean"
        ]
        assert list(line.y) == pytest.approx(means.tolist())
    for band in bands:  # upper edge out, lower edge back: six points, around the mean line
        assert len(band.x) == 6
        line = next(t for t in lines if t.name == band.legendgroup)
        assert all(
            hi >= m >= lo for hi, m, lo in zip(band.y[:3], line.y, band.y[:2:-1], strict=True)
        )


def test_heatmap_follows_the_paper_layout(grid3d: Path) -> None:
    study = load_study(grid3d)
    assert layout.heatmap_axes(study.varying) == ("robots.arm_speed", "feeder.rate", "belt.speed")
    fig = figures.heatmap_figure(study.best, "robots.arm_speed", "feeder.rate", "belt.speed", {})
    maps = [t for t in fig.data if t.type == "heatmap"]
    assert len(maps) == 2  # one panel per belt speed
    assert [a.text for a in fig.layout.annotations] == ["Belt speed 0.6 m/s", "Belt speed 1 m/s"]
    first = study.best[study.best["belt.speed"] == 0.6].set_index(
        ["feeder.rate", "robots.arm_speed"]
    )
    z = maps[0].z
    assert z[0][1] == pytest.approx(first.loc[(10, 4), "gripping_rate_mean"])
    assert maps[0].text[1][0] == first.loc[(15, 2), "policy"]  # cells name the winner
    assert sum(bool(m.showscale) for m in maps) == 1


def test_policy_figure_gaps_are_paired_differences(grid3d: Path) -> None:
    study = load_study(grid3d)
    fig = figures.policy_figure(study.paired, list(study.grid), study.policies)
    assert [t.name for t in fig.data] == ["SD", "FIFO"]
    fifo = next(t for t in fig.data if t.name == "FIFO")
    assert len(fifo.x) == 8
    paired = study.paired[study.paired["policy"] == "FIFO"].sort_values(list(study.grid))
    assert list(fifo.y) == pytest.approx(paired["diff_mean"].tolist())
    for trace in fig.data:  # the best policy of a point sits at zero, the others below
        for y, (ref,) in zip(trace.y, trace.customdata, strict=True):
            assert y == 0 if ref == trace.name else y <= 0


def test_timeline_and_belt_come_from_the_records(sweep3: Path) -> None:
    study = load_study(sweep3)
    assert study.parts is not None and study.spans is not None and study.run is not None
    fig = record_figures.timeline_figure(study.parts, study.spans, 10.0, 30.0, 4)
    busy = next(t for t in fig.data if t.name.startswith("Busy"))
    picked = study.parts[study.parts["outcome"] == "picked"]
    in_window = picked[(picked["placed_at"] > 10) & (picked["decided_at"] < 30)]
    assert len(busy.x) == len(in_window)
    assert (
        min(busy.base) >= 10.0
        and max(b + x for b, x in zip(busy.base, busy.x, strict=True)) <= 30.0
    )
    scenario = study.run["scenario"]
    belt = record_figures.belt_figure(study.parts, scenario, 12.0)
    on = record_figures.belt_positions(study.parts, scenario["belt"]["speed"], 12.0)
    assert sum(len(t.x) for t in belt.data) == sum(len(d) for d in on.values()) > 0
    for d in on.values():
        assert ((d["x"] >= 0) & (d["x"] <= 2.4)).all()
    assert len(belt.frames) == 51  # 5 s at 0.1 s
    rects = [s for s in belt.layout.shapes if s.type == "rect"]
    assert len(rects) == 1 + 4 + 4  # belt, workspaces, bins


def test_robots_figure_stacks_time_shares(sweep3: Path) -> None:
    study = load_study(sweep3)
    point, policy = layout.showcase_point(study)
    # the recorded run is the base line (the scenario's own arm speed, 3) with its best policy
    assert policy == study.run["policy"] and point == {"robots.arm_speed": 3}
    fig = record_figures.robots_figure(study.results, point, policy)
    stacked = [t for t in fig.data if t.xaxis == "x"]
    totals = [sum(t.y[i] for t in stacked) for i in range(4)]
    assert all(90 <= s <= 100.001 for s in totals)
    passed = next(t for t in fig.data if t.name.startswith("Passed on"))
    lost = next(t for t in fig.data if t.name.startswith("Lost"))
    runs = study.results[
        (study.results["robots.arm_speed"] == 3) & (study.results["policy"] == policy)
    ]
    assert passed.y[0] == pytest.approx(runs["r1_passed_on"].mean()) and passed.y[3] == 0
    assert lost.y[3] == pytest.approx(runs["r4_lost"].mean())
    assert lost.y[3] == pytest.approx(runs["parts_missed"].mean())


def test_sizing_sentence_names_the_answer(sizing: Path) -> None:
    data = json.loads((sizing / "sizing.json").read_text())
    assert data["answer"] is not None
    first = sizing_text(data)[0]
    assert f"needs {data['answer']} robots" in first
    assert "45.0 %" in first and "95 % confidence" in first
    assert any("N_min" in s for s in sizing_text(data))
    none = dict(data, answer=None)
    assert sizing_text(none)[0].startswith("None of the values tried (2 to 4) reaches")
    fig = figures.sizing_figure(data)
    assert list(fig.data[0].x) == [2, 3, 4]


def test_report_html_is_self_contained(grid3d: Path) -> None:
    html = render_report(grid3d)
    js = get_plotlyjs()
    assert html.count(js[:2000]) == 1  # plotly.js inlined exactly once
    assert html.count("Plotly.newPlot(") == 9  # 8 study figures and the warm-up plot
    assert 'content="9"' in html
    assert "<script src" not in html and "cdn." not in html.replace(js, "")
    assert "@import" not in html and "fonts.googleapis" not in html
    for heading in ("What was run", "Heatmaps", "Policy comparison", "Robots", "KPI summary"):
        assert f">{heading}</h2>" in html
    summary = pd.read_csv(grid3d / "summary.csv")
    top = summary["gripping_rate_mean"].max()
    assert fmt_pct(top) in html  # G in % with one decimal


def test_report_without_records_or_sizing_still_builds(grid3d: Path, tmp_path: Path) -> None:
    bare = tmp_path / "bare"
    shutil.copytree(grid3d, bare, ignore=shutil.ignore_patterns("records", "report.html"))
    for name in ("paired.csv", "best.csv", "results.parquet", "results.csv"):
        (bare / name).unlink()
    out = build_report(bare)
    assert out == bare / "report.html"
    html = out.read_text(encoding="utf-8")
    assert "One run up close" not in html and "Policy comparison" not in html
    assert "Heatmaps" in html  # best.csv is rebuilt from summary.csv
    assert "No run records" in html
    assert not list(bare.glob(".report.html.*"))  # no temp file left behind


def test_single_point_single_policy_study(tmp_path: Path) -> None:
    folder = make_study(tmp_path / "one", grid={}, policies=("SD",), replications=2)
    study = load_study(folder)
    page = layout.build_page(study)
    titles = [s.title for s in page.sections]
    assert "Gripping rate against each parameter" not in titles
    assert "Heatmaps" not in titles and "Policy comparison" not in titles
    assert page.figures == 4  # robots, timeline, belt, warm-up: never an empty chart
    assert key_findings(study)[0].startswith("Highest mean gripping rate")
    assert reference_point(study) == {}


def test_mix_report_ranks_the_mixes(mix2: Path) -> None:
    html = render_report(mix2)
    mix = json.loads((mix2 / "mix.json").read_text())
    assert "Rule-mix ranking" in html and "4 mixes evaluated (exhaustive: every mix)" in html
    table = html[html.index("<table", html.index('id="mix"')) :]
    table = table[: table.index("</table>")]
    assert table.count("<tr") == 1 + 4  # header and every mix
    assert '<th class="l">Robot 1</th><th class="l">Robot 2</th>' in table
    rows = table.split("<tr")[2:]
    for rank, (row, r) in enumerate(zip(rows, mix["ranked"], strict=True), start=1):
        assert f">{rank}</td>" in row
        assert "".join(f'<td class="l">{rule}</td>' for rule in r["mix"].split(",")) in row


def test_formats_for_humans() -> None:
    assert fmt_pct(72.345) == "72.3 %"
    assert fmt_pct(float("nan")) == "–"
    assert fmt_pm(70.0, 73.0) == "± 1.5"
    assert fmt_pm(float("nan"), 1.0) == ""


def test_not_a_study_folder_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ReportError) as e:
        load_study(tmp_path)
    assert "meta.json" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ReportError):
        load_study(tmp_path / "missing")
    (tmp_path / "meta.json").write_text("{not json")
    with pytest.raises(ReportError) as e:
        load_study(tmp_path)
    assert "cannot read JSON" in str(e.value)


def answer_of(html: str) -> str:
    """The first sentence of the page: the answer box that opens the report."""
    start = html.index('<section id="answer">')
    assert html.index("<section id=") == start  # the answer is the report's first section
    first = html[start:].split('<div class="answer"><p>', 1)[1]
    return first.split("</p>", 1)[0]


def test_every_report_opens_with_its_answer(sweep3: Path, sizing: Path, mix2: Path) -> None:
    for folder in (sweep3, sizing, mix2):
        html = render_report(folder)
        sections = re.findall(r'<section id="(\w+)"', html)
        assert sections[0] == "answer", (folder, sections)
        assert answer_of(html) == html_escape(headline(load_study(folder)))


def test_sweep_answer_names_the_best_policy_where_it_matters(grid3d: Path) -> None:
    study = load_study(grid3d)
    text = headline(study)
    wins = study.best["policy"].value_counts()
    here = study.best[
        (study.best["robots.arm_speed"] == 2)
        & (study.best["feeder.rate"] == 10)
        & (study.best["belt.speed"] == 0.6)
    ]
    top = here["policy"].iloc[0]  # the answer names the best policy where it looks (issue 19)
    assert text.startswith(f"{top} is the best policy at the middle of the grid (arm speed 2 m/s")
    assert "the middle of the grid (arm speed 2 m/s, part flow 10 parts/s, belt speed 0.6" in text
    assert f"{wins.iloc[0]} of 8 grid points" in text
    assert "; at the hardest point (" in text and "95 % CI" in text


def test_size_answer_is_n_robots_g_with_ci_and_the_rule_of_thumb(sizing: Path) -> None:
    data = json.loads((sizing / "sizing.json").read_text())
    text = size_headline(data)
    n = data["answer"]
    row = next(r for r in data["rows"] if r["robots.count"] == n and r["robots.mtbf"] == 0)
    assert text.startswith(f"{n} robots running {data['rule']} reach G ≥ 45 % with 95 % confidence")
    assert f"{row['gripping_rate_mean']:.1f} % (95 % CI {row['ci_low']:.1f} to" in text
    assert text.endswith(f"the rule of thumb says {data['rule_of_thumb']['n_recommended']}.")


def test_mix_answer_says_when_the_two_best_cannot_be_told_apart(mix2: Path) -> None:
    mix = json.loads((mix2 / "mix.json").read_text())
    best, second = mix["ranked"][0]["mix"], mix["ranked"][1]["mix"]
    tied = dict(mix, margin=dict(mix["margin"], ci_low=-0.3, ci_high=0.5, distinguishable=False))
    text = mix_headline(tied)
    assert text.startswith(f"Best rule mix: {best} (robot 1 first), G = ")
    assert f"cannot be told apart from {second}" in text and "paired 95 % CI -0.30 to 0.50" in text
    assert "points ahead" not in text
    apart = dict(
        mix,
        margin=dict(mix["margin"], diff_mean=1.2, ci_low=0.4, ci_high=2.0, distinguishable=True),
    )
    assert f"1.20 points ahead of {second} (paired 95 % CI 0.40 to 2.00)" in mix_headline(apart)


def test_size_report_states_the_target_used_and_draws_the_layout(sizing: Path) -> None:
    html = render_report(sizing)
    lead = html.split('<p class="lead">', 1)[1].split("</p>", 1)[0]
    assert lead.startswith("Target used: gripping rate ≥ 45 % with 95 % confidence · layout extend")
    data = json.loads((sizing / "sizing.json").read_text())
    fig = figures.layout_figure(data)
    rects = [s for s in fig.layout.shapes if s.type == "rect"]
    counts = data["layout"]["counts"]
    assert len(rects) == sum(1 + len(c["workspaces"]) for c in counts.values())
    assert "Layout: extend" in fig.layout.title.text
    assert "Layout: extend." in html


def test_robots_and_the_run_up_close_show_the_recommended_line(sizing: Path) -> None:
    study = load_study(sizing)
    answer = study.sizing["answer"]
    point, policy = layout.showcase_point(study)
    assert point["robots.count"] == answer and point["robots.mtbf"] == 0
    assert study.run is not None and study.run["scenario"]["robots"]["count"] == answer


def test_names_are_never_cut_mid_word() -> None:
    names = ", ".join(["SPT,SPT,SPT,FIFO", "SD,SD,SD,SD", "LIFO,LIFO,LIFO,LIFO"] * 3)
    short = layout.shorten(names, 60)
    assert len(short) <= 62 and short.endswith(" …")
    kept = short[:-2].split(", ")
    assert all(k in names.split(", ") for k in kept)


def test_the_belt_says_will_be_missed_and_animates_a_minute(sweep3: Path) -> None:
    study = load_study(sweep3)
    html = render_report(sweep3)
    assert "will be missed" in html and '"name":"missed"' not in html
    page = layout.build_page(study)
    belt = next(i for s in page.sections for i in s.items if getattr(i, "frames", None))
    times = [float(f.name) for f in belt.frames]
    assert times[0] == 10.0 and times[-1] == pytest.approx(60.0)  # the run ends at 60 s


def test_the_belt_animation_covers_the_chosen_window(sweep3: Path, tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from pnp_twin.cli import app
    from pnp_twin.reports.record_figures import Animation

    page = layout.build_page(load_study(sweep3), Animation(start=30.0, seconds=10.0, step=0.5))
    belt = next(i for s in page.sections for i in s.items if getattr(i, "frames", None))
    times = [float(f.name) for f in belt.frames]
    assert times[0] == 30.0 and times[-1] == pytest.approx(40.0) and len(times) == 21
    out = tmp_path / "r.html"
    args = ["report", str(sweep3), "--out", str(out), "--animate-from", "50"]
    result = CliRunner().invoke(app, [*args, "--animate-seconds", "5"])
    assert result.exit_code == 0, result.output
    html = out.read_text()
    assert '"name":"50.0"' in html and '"name":"55.0"' in html and '"name":"55.2"' not in html
    assert '"name":"30.0"' not in html


def test_print_css_lets_every_row_onto_paper(grid3d: Path) -> None:
    html = render_report(grid3d)
    css = html.split("@media print {", 1)[1]
    assert ".scroll { max-height:none !important; overflow:visible !important;" in css
    assert "thead { display:table-header-group; }" in css


def test_welch_plot_marks_the_warm_up_and_flags_a_drift() -> None:
    t_bins = 60
    steady = np.tile(np.full(t_bins, 70.0), (5, 1)) + np.random.default_rng(0).normal(
        0, 1, (5, t_bins)
    )
    a = welch.analyse(steady, 600.0, 60.0)
    assert not a["drift"]["drifting"] and "looks long enough" in welch.note(a, 60.0)
    rising = steady + np.linspace(0, 6, t_bins)  # G still climbs 6 points over the run
    b = welch.analyse(rising, 600.0, 60.0)
    assert b["drift"]["drifting"] and b["drift"]["change"] > 2
    assert welch.note(b, 60.0).startswith("Warning: G is still drifting after the 60 s warm-up")
    fig = welch.welch_figure(b, 60.0, 600.0, "SD")
    assert any(s.x0 == 60.0 and s.x1 == 60.0 for s in fig.layout.shapes)  # the marker
    smooth = welch.moving_average(np.arange(10.0), 2)
    assert (
        smooth[:8].tolist() == pytest.approx([0, 1, 2, 3, 4, 5, 6, 7])
        and np.isnan(smooth[8:]).all()
    )


def test_every_study_report_has_a_welch_plot(sweep3: Path, sizing: Path, mix2: Path) -> None:
    for folder in (sweep3, sizing, mix2):
        html = render_report(folder)
        assert '<section id="warmup">' in html and "Welch" in html, folder


def test_an_auto_replication_study_states_the_precision_reached(
    sweep3: Path, tmp_path: Path
) -> None:
    folder = tmp_path / "auto"
    shutil.copytree(sweep3, folder, ignore=shutil.ignore_patterns("report.html"))
    meta = json.loads((folder / "meta.json").read_text())
    meta["precision"] = {
        "kpi": "gripping_rate",
        "target_half_width": 0.5,
        "max_replications": 30,
        "confidence": 0.95,
        "replications": 11,
        "rounds": [3, 6, 11],
        "reached": True,
        "points_short": 0,
        "half_width_max": 0.48,
        "worst": {"point": 1, "policy": "SD"},
    }
    (folder / "meta.json").write_text(json.dumps(meta))
    html = render_report(folder)
    assert "Replications chosen for precision (3 → 6 → 11 in rounds): every point" in html
    assert "at most ± 0.5 points (widest ± 0.48)" in html
    meta["precision"].update(reached=False, points_short=2, half_width_max=0.9, rounds=[3, 30])
    (folder / "meta.json").write_text(json.dumps(meta))
    assert "2 point(s) still have a 95 % CI of G wider than ± 0.5 points" in render_report(folder)
    assert "Replications chosen" not in render_report(sweep3)
