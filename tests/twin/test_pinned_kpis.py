"""The shipped scenarios' KPIs and the README's figures, pinned (issue 18).

``tests/pinned/kpis.json`` is written by ``bench/pin_kpis.py`` (run it when the model changes on
purpose, then update the README from what it prints). Here the short runs are rerun and
compared to the last bit (1e-12 relative), and the README is checked to hold the pinned
figures (the rule ranking and the calibration table; recomputing those takes minutes, which
``bench/pin_kpis.py --check`` does)."""

from __future__ import annotations

import json
from typing import Any

import pytest

from bench.pin_kpis import (
    KPI_KEYS,
    OUTFEED_KEYS,
    PINNED,
    README,
    SHIPPED,
    differences,
    readme_holds,
    readme_text,
    short_kpis,
)

PIN: dict[str, Any] = json.loads(PINNED.read_text())
RUNS = PIN["short"]["runs"]


def test_every_shipped_scenario_is_pinned() -> None:
    from pnp_twin.twin.loader import shipped_scenarios

    assert set(shipped_scenarios()) == set(SHIPPED)  # a new shipped scenario gets pinned too
    assert {r["scenario"] for r in RUNS} == set(SHIPPED)
    assert {r["policy"] for r in RUNS if r["scenario"] == "paper_baseline"} == {
        None, "FIFO", "LIFO", "SIRO", "SD", "LD", "SPT"
    }  # fmt: skip


@pytest.mark.parametrize("run", RUNS, ids=[f"{r['scenario']}-{r['policy'] or 'own'}" for r in RUNS])
def test_a_short_run_gives_its_pinned_kpis(run: dict[str, Any]) -> None:
    got = short_kpis(run["scenario"], run["policy"])
    outfeed = run["scenario"].startswith("tray_loading")  # the shipped lines with an outfeed
    assert set(got) == {*KPI_KEYS, *(OUTFEED_KEYS if outfeed else ()), "robots"}
    assert differences(got, run["kpis"]) == []


def test_differences_sees_a_change_in_the_last_digits() -> None:
    pinned = RUNS[0]["kpis"]
    moved = {**pinned, "gripping_rate": pinned["gripping_rate"] * (1 + 1e-10)}
    assert differences(moved, pinned) == [
        f".gripping_rate: {moved['gripping_rate']!r}, pinned {pinned['gripping_rate']!r}"
    ]
    fewer = {**pinned, "robots": pinned["robots"][:-1]}
    assert differences(fewer, pinned) != []


def test_the_readme_holds_the_pinned_figures() -> None:
    readme = PIN["readme"]
    lines = readme_text(readme)
    assert lines == readme["text"]  # the pinned text is what the pinned figures format to
    assert readme_holds(lines, README.read_text(encoding="utf-8")) == []
    # the ranking the README states: SPT 68.5 %, SD 68.4 %, FIFO, SIRO, LIFO, LD
    r = readme["ranking"]
    assert sorted(r, key=lambda k: -r[k]) == ["SPT", "SD", "FIFO", "SIRO", "LIFO", "LD"]
    assert lines[0] == "SPT 68.5 %"


def test_a_drifted_readme_figure_is_caught() -> None:
    text = README.read_text(encoding="utf-8")
    lines = PIN["readme"]["text"]
    assert readme_holds(lines, text.replace("SD 68.4 %", "SD 68.3 %")) == ["SD 68.4 %"]
    assert readme_holds(lines, text.replace("69.18 [68.19", "69.17 [68.19")) == [lines[-2]]
