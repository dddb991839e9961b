"""The runs store (``evals/runs.sqlite``): rows read back exactly, one committed row per run,
readable with plain SQL, a damaged or newer store refused in one line, an older folder's
log migrated once."""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.runstore import (
    SCHEMA_VERSION,
    STORE_FILE,
    RunStore,
    open_store,
    store_rows,
    stored_runs,
)

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"


def test_rows_read_back_exactly_and_by_plain_sql(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    row = {"gripping_rate": 91.25, "part_flow": math.nan, "wait": math.inf, "n": 3, "unit": "x"}
    row |= {"text": "NaN", "none": None}  # a text and a None stay what they are
    store.add("k1", row, label="robots.count=3, SD", point={"robots.count": 3}, policy="SD", seed=7)
    back = store.get("k1")
    row_rest = {"text": "NaN", "none": None}
    assert back is not None and math.isnan(back.pop("part_flow"))
    assert back == {"gripping_rate": 91.25, "wait": math.inf, "n": 3, "unit": "x", **row_rest}
    assert store.get("absent") is None and len(store) == 1
    db = sqlite3.connect(tmp_path / STORE_FILE)  # a user's own SQL, while the store is open
    found = db.execute(
        "SELECT policy, seed, json_extract(point, '$.\"robots.count\"'), "
        "json_extract(kpis, '$.gripping_rate'), json_extract(kpis, '$.part_flow') FROM runs"
    ).fetchall()
    assert found == [("SD", 7, 3, 91.25, None)]
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    db.close()
    assert stored_runs(tmp_path) == 1
    (flat,) = store_rows(tmp_path)
    assert flat["key"] == "k1" and flat["robots.count"] == 3 and flat["gripping_rate"] == 91.25


def test_each_run_is_committed_when_add_returns(tmp_path: Path) -> None:
    """Another connection (a process after a kill) sees the run at once, never closed."""
    store = RunStore(tmp_path)
    store.add("k", {"gripping_rate": 50.0})
    other = sqlite3.connect(tmp_path / STORE_FILE)
    assert other.execute("SELECT count(*) FROM runs").fetchone()[0] == 1
    other.close()


@pytest.mark.parametrize(
    ("content", "why"),
    [(b"not a database, a text file" * 100, "damaged"), (None, "newer pnp-twin")],
    ids=["not-sqlite", "newer"],
)
def test_a_damaged_or_newer_store_is_one_line(tmp_path: Path, content, why) -> None:
    path = tmp_path / STORE_FILE
    if content is None:
        RunStore(tmp_path).close()
        db = sqlite3.connect(path)
        db.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
        db.close()
    else:
        path.write_bytes(content)
    with pytest.raises(StudyError) as e:
        RunStore(tmp_path)
    assert why in str(e.value) and str(path) in str(e.value) and "\n" not in str(e.value)


def test_a_damaged_row_is_run_again(tmp_path: Path, caplog) -> None:
    store = RunStore(tmp_path)
    store.add("k", {"gripping_rate": 50.0})
    db = sqlite3.connect(tmp_path / STORE_FILE)
    with db:
        db.execute("UPDATE runs SET kpis = '{broken' WHERE key = 'k'")
    db.close()
    assert store.get("k") is None and "damaged" in caplog.text


def test_a_refused_block_leaves_no_empty_store(tmp_path: Path) -> None:
    with pytest.raises(StudyError), open_store(tmp_path / "a"):
        raise StudyError("refused")
    assert not list((tmp_path / "a").iterdir())
    with pytest.raises(StudyError), open_store(tmp_path / "b") as store:
        store.add("k", {"gripping_rate": 50.0})
        raise StudyError("failed after a run")
    assert stored_runs(tmp_path / "b") == 1  # a stored run is never thrown away


def test_a_design_on_a_damaged_store_exits_2_in_one_line(tmp_path: Path) -> None:
    out = tmp_path / "d"
    (out / "evals").mkdir(parents=True)
    (out / "evals" / STORE_FILE).write_bytes(b"\x00garbage" * 512)
    args = ["design", str(BASELINE), "--target", "80", "--vary", "robots.count=2,3", "-r", "2",
            "--max-replications", "2", "--set", "duration=20", "--set", "warmup=4",
            "--no-report", "--out", str(out), "--workers", "1"]  # fmt: skip
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert "runs.sqlite: is damaged" in result.stderr and "Traceback" not in result.output
    assert len(result.stderr.strip().splitlines()) == 1


def test_a_design_folder_exports_its_stored_runs(tmp_path: Path) -> None:
    """``export`` reads the store: one row per run with its values, policy, seed, KPIs."""
    import pandas as pd

    out = tmp_path / "d"
    args = ["design", str(BASELINE), "--target", "80", "--vary", "robots.count=2,3", "-r", "2",
            "--max-replications", "2", "-p", "SD", "--set", "duration=20", "--set", "warmup=4",
            "--no-report", "--out", str(out), "--workers", "1"]  # fmt: skip
    assert CliRunner().invoke(app, args).exit_code == 0
    book = tmp_path / "d.xlsx"
    result = CliRunner().invoke(app, ["export", str(out), "--xlsx", str(book)])
    assert result.exit_code == 0, result.output
    runs = pd.read_excel(book, sheet_name="runs")
    assert len(runs) == 4 == stored_runs(out / "evals")
    assert sorted(runs["robots.count"]) == [2, 2, 3, 3] and set(runs["policy"]) == {"SD"}
    assert runs["gripping_rate (%)"].between(0, 100).all() and runs["seed"].nunique() == 2
