"""A study folder as one Excel workbook: results, summary, paired and best as sheets.

``export_xlsx(DIR, FILE)`` reads the folder's tables (``docs/study_format.md``) and writes
them, one sheet each, with the unit of every column in its header, e.g.
``gripping_rate_mean (%)``, ``throughput_mean (parts/s)``, ``robots.arm_speed (m/s)``.
One unit convention throughout: the gripping rate, efficiency, utilisation and every other
time share are percentages (the folder stores the shares as fractions; they are scaled by
100 here and say so with ``(%)``). Nothing is simulated.

A folder whose runs are in a runs store (``DIR/evals/runs.sqlite``: ``design``, ``capacity``,
``calibrate``, ``headroom``) gets a ``runs`` sheet too, one row per stored run (its key,
label, varied values, policy, seed and KPIs); such a folder without ``meta.json`` is
exported as that one sheet.
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path
from typing import Any

import pandas as pd
from pydantic import BaseModel

from pnp_twin.studies.calibrate_eval import EVALS
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.runstore import STORE_FILE, store_rows
from pnp_twin.twin.output import atomic_path
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

SHEETS = ("results", "summary", "paired", "best")
STATS = r"(_mean|_ci_low|_ci_high)?"
# (pattern over a column name, unit, factor to the unit)
UNITS: list[tuple[str, str, float]] = [
    (rf"gripping_rate{STATS}", "%", 1.0),
    (rf"(efficiency|utilisation){STATS}", "%", 100.0),
    (r"r\d+_(utilisation|noop|wait|blocked|down|availability)", "%", 100.0),
    (rf"(throughput|part_flow|max_throughput){STATS}", "parts/s", 1.0),
    (r"r\d+_(throughput|capacity|nominal_capacity)", "parts/s", 1.0),
    (r"(r\d+_)?cycle_time_\w+", "s", 1.0),
    (r"wall_time", "s", 1.0),
    (r"rule_NooP", "decisions", 1.0),  # NooP decisions taken, not parts
    (r"rule_\w+", "picks", 1.0),  # picks decided by that rule
    (r"parts_\w+|r\d+_(picks|passed_on|lost)", "parts", 1.0),
    (r"diff(_mean|_ci_low|_ci_high)", "points of G", 1.0),
]


def field_unit(path: str) -> str:
    """The unit a dotted scenario path carries in the Scenario model, or ''."""
    model: type[BaseModel] = Scenario
    info = None
    for key in path.split("."):
        info = model.model_fields.get(key)
        if info is None:
            return ""
        ann = info.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            model = ann
    extra = info.json_schema_extra if info is not None else None
    return str(extra.get("unit", "")) if isinstance(extra, dict) else ""


def with_units(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with shares scaled to % and the unit of each column in its header."""
    out = frame.copy()
    names = {}
    for col in out.columns:
        unit, factor = "", 1.0
        for pattern, u, f in UNITS:
            if re.fullmatch(pattern, str(col)):
                unit, factor = u, f
                break
        else:
            unit = field_unit(str(col)) if "." in str(col) else ""
        if factor != 1.0:
            out[col] = pd.to_numeric(out[col], errors="coerce") * factor
        names[col] = f"{col} ({unit})" if unit else str(col)
    return out.rename(columns=names)


SERIES = "welch_gripping_rate"  # JSON text of a list per run: its own sheet, long format
TEXT_COLUMNS = ("seed", "master_seed")  # 16-digit integers Excel would round: kept as text


def for_excel(frame: pd.DataFrame, meta: dict[str, Any]) -> pd.DataFrame:
    """``frame`` as a sheet: no list column, seeds as text (Excel keeps 15 digits), and the
    MTTR beside a swept MTBF when the study held it fixed (a sizing study's breakdowns)."""
    out = frame.drop(columns=[SERIES], errors="ignore").copy()
    for col in TEXT_COLUMNS:
        if col in out.columns:
            out[col] = [str(v) if pd.notna(v) else "" for v in out[col]]
    mttr = ((meta.get("scenario") or {}).get("robots") or {}).get("mttr")
    if "robots.mtbf" in out.columns and "robots.mttr" not in out.columns and mttr is not None:
        where = list(out.columns).index("robots.mtbf") + 1
        out.insert(where, "robots.mttr", [float(mttr) if m else 0.0 for m in out["robots.mtbf"]])
    return out


def series_sheet(results: pd.DataFrame) -> pd.DataFrame | None:
    """The per-run Welch series (G per 1/60 of the feeding period) as rows run_id, bin, G."""
    if SERIES not in results.columns or "run_id" not in results.columns:
        return None
    rows = []
    for run, text in zip(results["run_id"], results[SERIES], strict=True):
        try:
            values = json.loads(text) if isinstance(text, str) else []
        except ValueError:
            continue
        for i, g in enumerate(values, start=1):
            rows.append({"run_id": run, "bin": i, "gripping_rate": g})
    return pd.DataFrame(rows) if rows else None


def read_sheet(folder: Path, stem: str) -> pd.DataFrame | None:
    """``stem``.parquet, else ``stem``.csv of ``folder``; None when neither exists."""
    for suffix, reader in ((".parquet", pd.read_parquet), (".csv", pd.read_csv)):
        path = folder / f"{stem}{suffix}"
        if path.is_file():
            try:
                frame: pd.DataFrame = reader(path)
            except Exception as e:  # a broken table: one line naming it
                raise StudyError(f"{path}: cannot read table ({type(e).__name__})") from None
            return frame
    return None


def export_xlsx(folder: Path | str, out: Path | str) -> dict[str, Any]:
    """Write the study in ``folder`` to the workbook ``out``; the sheets and their rows."""
    folder, out = Path(folder), Path(out)
    stored = (folder / EVALS / STORE_FILE).is_file()
    if not (folder / "meta.json").is_file() and not stored:
        raise StudyError(f"{folder}: no meta.json, so not a study folder (see pnp-twin sweep)")
    if out.suffix.lower() != ".xlsx":
        raise StudyError(f"--xlsx {out}: give a file name ending in .xlsx")
    tables = {s: t for s in SHEETS if (t := read_sheet(folder, s)) is not None}
    if "summary" not in tables and not stored:
        raise StudyError(f"{folder}: summary.csv is missing; finish the study first")
    if stored:
        tables["runs"] = pd.DataFrame(store_rows(folder / EVALS))
    try:
        meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        meta = {}
    meta = meta if isinstance(meta, dict) else {}
    series = series_sheet(tables["results"]) if "results" in tables else None
    with atomic_path(out) as tmp, pd.ExcelWriter(tmp, engine="openpyxl") as xl:
        for name, table in tables.items():
            with_units(for_excel(table, meta)).to_excel(xl, sheet_name=name, index=False)
            xl.sheets[name].freeze_panes = "A2"
        if series is not None:
            with_units(series).to_excel(xl, sheet_name="welch", index=False)
            xl.sheets["welch"].freeze_panes = "A2"
            tables = {**tables, "welch": series}
    log.info("exported %s to %s", folder, out)
    return {name: len(t) for name, t in tables.items()}
