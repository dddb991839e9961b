"""Reading a study folder (the format of ``docs/study_format.md``) into one ``Study`` object.

Only ``meta.json`` and ``summary.csv`` are required; every other table is optional and the
report leaves out what it cannot show. Nothing here simulates: the report is built from the
tables the study wrote.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.twin.errors import UserError

log = logging.getLogger(__name__)


class ReportError(UserError):
    """The folder is not a study folder, or one of its files cannot be read."""


@dataclass(frozen=True)
class Study:
    """Everything a report shows, as read from one study folder."""

    path: Path
    meta: dict[str, Any]
    summary: pd.DataFrame
    grid: dict[str, list[Any]]
    results: pd.DataFrame | None = None
    paired: pd.DataFrame | None = None
    best: pd.DataFrame | None = None
    parts: pd.DataFrame | None = None
    spans: pd.DataFrame | None = None
    run: dict[str, Any] | None = None
    sizing: dict[str, Any] | None = None
    mix: dict[str, Any] | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def policies(self) -> list[str]:
        """Policies in the order the study lists them (then any others found in the table)."""
        listed = [str(p) for p in self.meta.get("policies") or []]
        found = [str(p) for p in pd.unique(self.summary["policy"])]
        return [p for p in listed if p in found] + [p for p in found if p not in listed]

    @property
    def varying(self) -> list[str]:
        """Grid parameters that take two values or more, in the study's order."""
        return [p for p, values in self.grid.items() if len(values) >= 2]

    @property
    def scenario_name(self) -> str:
        scenario = self.meta.get("scenario") or {}
        return str(self.meta.get("scenario_name") or scenario.get("name") or self.path.name)


def read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``, or a one-line ReportError naming the file."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise ReportError(f"{path}: cannot read JSON ({type(e).__name__}: {e})") from None
    if not isinstance(data, dict):
        raise ReportError(f"{path}: expected a JSON object, found {type(data).__name__}")
    return data


def read_table(folder: Path, stem: str) -> pd.DataFrame | None:
    """``stem``.parquet, else ``stem``.csv, else None; a broken file is a ReportError."""
    for suffix, reader in ((".parquet", pd.read_parquet), (".csv", pd.read_csv)):
        path = folder / f"{stem}{suffix}"
        if path.is_file():
            try:
                return reader(path)
            except Exception as e:  # any parser error: report the file, not a traceback
                raise ReportError(f"{path}: cannot read table ({type(e).__name__})") from None
    return None


def grid_of(meta: dict[str, Any], summary: pd.DataFrame) -> dict[str, list[Any]]:
    """Grid parameters present in the summary, each with its sorted distinct values."""
    grid: dict[str, list[Any]] = {}
    for path in meta.get("grid") or {}:
        if path in summary.columns:
            values = pd.unique(summary[path].dropna())
            grid[path] = sorted(values.tolist())
        else:
            log.warning("grid parameter %s is not a column of summary.csv; ignored", path)
    return grid


def best_from_summary(summary: pd.DataFrame, grid: list[str]) -> pd.DataFrame:
    """One row per grid point: the policy with the highest mean gripping rate."""
    if not grid:
        top = summary.loc[[summary["gripping_rate_mean"].idxmax()]]
    else:
        idx = summary.groupby(grid, sort=True)["gripping_rate_mean"].idxmax()
        top = summary.loc[idx.to_numpy()]
    return top[[*grid, "policy", "gripping_rate_mean"]].reset_index(drop=True)


def load_study(study_dir: Path | str) -> Study:
    """Read the study folder ``study_dir``; raises ReportError when it is not one."""
    folder = Path(study_dir)
    if not folder.is_dir():
        raise ReportError(
            f"{folder}: no such folder; give a study folder written by sweep/size/mix"
        )
    if not (folder / "meta.json").is_file():
        raise ReportError(f"{folder}: no meta.json, so not a study folder (see pnp-twin sweep)")
    meta = read_json(folder / "meta.json")
    summary = read_table(folder, "summary")
    if summary is None or summary.empty:
        raise ReportError(f"{folder}: summary.csv is missing or empty; finish the study first")
    missing = {"policy", "gripping_rate_mean"} - set(summary.columns)
    if missing:
        raise ReportError(f"{folder / 'summary.csv'}: missing columns {sorted(missing)}")
    summary["policy"] = summary["policy"].astype(str)
    grid = grid_of(meta, summary)
    notes: list[str] = []
    best = read_table(folder, "best")
    if best is None or not set(grid) <= set(best.columns):
        best = best_from_summary(summary, list(grid))
    best["policy"] = best["policy"].astype(str)
    paired = read_table(folder, "paired")
    if paired is not None:
        paired["policy"] = paired["policy"].astype(str)
        paired["reference"] = paired["reference"].astype(str)
    results = read_table(folder, "results")
    if results is not None:
        results["policy"] = results["policy"].astype(str)
    records = folder / "records"
    parts = read_table(records, "parts")
    spans = read_table(records, "spans")
    run = read_json(records / "run.json") if (records / "run.json").is_file() else None
    if parts is None or spans is None or run is None:
        notes.append("No run records in this folder: the timeline and belt view are left out.")
        parts = spans = run = None
    sizing = read_json(folder / "sizing.json") if (folder / "sizing.json").is_file() else None
    mix = read_json(folder / "mix.json") if (folder / "mix.json").is_file() else None
    return Study(
        path=folder,
        meta=meta,
        summary=summary,
        grid=grid,
        results=results,
        paired=paired,
        best=best,
        parts=parts,
        spans=spans,
        run=run,
        sizing=sizing,
        mix=mix,
        notes=notes,
    )
