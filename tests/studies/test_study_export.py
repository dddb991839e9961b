"""``pnp-twin export STUDY --xlsx FILE``: the study's tables as sheets, units in the headers."""

from __future__ import annotations

from pathlib import Path

import openpyxl
import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.export import export_xlsx, field_unit, with_units
from pnp_twin.studies.plan import StudyError
from tests.study_fixture import make_study


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("export") / "sweep"
    return make_study(folder, grid={"robots.arm_speed": [2, 4]}, duration=30.0, warmup=5.0)


def sheet(path: Path, name: str) -> pd.DataFrame:
    return pd.read_excel(path, sheet_name=name, engine="openpyxl")


def test_every_table_is_a_sheet_with_units_and_percentages(study: Path, tmp_path: Path) -> None:
    out = tmp_path / "study.xlsx"
    result = CliRunner().invoke(app, ["export", str(study), "--xlsx", str(out)])
    assert result.exit_code == 0, result.stderr
    sheets = ["results", "summary", "paired", "best", "welch"]  # welch: the per-run series
    assert openpyxl.load_workbook(out).sheetnames == sheets
    summary = pd.read_csv(study / "summary.csv")
    s = sheet(out, "summary")
    assert len(s) == len(summary)
    assert s["gripping_rate_mean (%)"].tolist() == pytest.approx(summary["gripping_rate_mean"])
    # shares are fractions in the CSV and percentages in the workbook, and say so
    assert s["efficiency_mean (%)"].tolist() == pytest.approx(100 * summary["efficiency_mean"])
    assert s["utilisation_mean (%)"].tolist() == pytest.approx(100 * summary["utilisation_mean"])
    assert "throughput_mean (parts/s)" in s.columns and "robots.arm_speed (m/s)" in s.columns
    r = sheet(out, "results")
    assert {"r1_availability (%)", "r1_passed_on (parts)", "cycle_time_p95 (s)"} <= set(r.columns)
    assert "diff_mean (points of G)" in sheet(out, "paired").columns
    assert "wrote" in result.stderr and "summary 4 rows" in result.stderr


def test_units_come_from_the_scenario_model() -> None:
    assert field_unit("robots.arm_speed") == "m/s" and field_unit("feeder.rate") == "parts/s"
    assert field_unit("belt.length") == "m" and field_unit("robots.nothing") == ""
    frame = with_units(pd.DataFrame({"r2_down": [0.25], "policy": ["SD"]}))
    assert list(frame.columns) == ["r2_down (%)", "policy"] and frame.iloc[0, 0] == 25.0


def test_not_a_study_is_a_one_line_error(tmp_path: Path) -> None:
    with pytest.raises(StudyError, match="no meta.json, so not a study folder"):
        export_xlsx(tmp_path, tmp_path / "x.xlsx")
    result = CliRunner().invoke(app, ["export", str(tmp_path), "--xlsx", str(tmp_path / "x.xlsx")])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith("error: ")
    result = CliRunner().invoke(app, ["export", str(tmp_path)])
    assert result.exit_code == 2 and "give --xlsx FILE.xlsx" in result.stderr
