"""The measured points a calibration fits: a CSV, one row per point.

Columns (header row; lines starting with ``#`` are comments, e.g. the data's source):

- one per scenario field that differs between the points, by its dotted path as ``--set``
  takes it (``robots.arm_speed``, ``feeder.rate``, ``robots.bin_offset.1``);
- one per observed KPI, by its ``--json`` / study-table name: ``gripping_rate`` (%, at least
  this or another KPI), ``throughput`` (picks/s), ``efficiency``, ``utilisation``, or one
  robot's ``r2_throughput`` / ``r2_picks`` (picks of robot 2 per second / in the window); a
  cell may be empty where that KPI was not measured at that point;
- optionally ``weight`` (>= 0, default 1): how much the point counts.

Residuals are made comparable across KPIs before they are squared: gripping rate in points
of percent, every other KPI in percent of its mean target (so a throughput 1 % off weighs as
much as a gripping rate one point off).
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pnp_twin.studies.calibrate_fields import FieldRef, resolve_path
from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.errors import clip
from pnp_twin.twin.inputs import TARGETS_BYTES, read_user_text
from pnp_twin.twin.loader import parse_value

WEIGHT = "weight"
LINE_KPIS = (
    "gripping_rate",
    "throughput",
    "efficiency",
    "utilisation",
    "parts_picked",
    "parts_missed",
    "cycle_time_mean",
)
ROBOT_KPI = re.compile(r"^r([1-9][0-9]*)_(picks|throughput|utilisation|missed|cycle_time_mean)$")


def is_kpi(name: str) -> bool:
    """Whether a column names a KPI the calibration can predict."""
    return name in LINE_KPIS or ROBOT_KPI.match(name) is not None


@dataclass(frozen=True)
class Targets:
    """The measured points: varied fields, KPIs, target values and weights."""

    source: str
    varied: tuple[FieldRef, ...]
    kpis: tuple[str, ...]
    values: tuple[tuple[Any, ...], ...]  # per point, one value per varied field
    target: np.ndarray  # points x kpis, NaN where not measured
    weight: np.ndarray  # per point

    @property
    def n(self) -> int:
        """Number of points."""
        return len(self.values)

    def point(self, i: int) -> dict[FieldRef, Any]:
        """The varied fields' values of point ``i``."""
        return dict(zip(self.varied, self.values[i], strict=True))

    def scale(self) -> np.ndarray:
        """Per KPI, what one unit of residual is (see the module docstring)."""
        out = []
        for j, k in enumerate(self.kpis):
            if k == "gripping_rate":
                out.append(1.0)
                continue
            mean = float(np.nanmean(np.abs(self.target[:, j])))
            out.append(0.01 * mean if mean > 0 else 1.0)
        return np.array(out)


def _cell(value: Any) -> Any:
    if isinstance(value, str):
        return parse_value(value.strip())
    if isinstance(value, np.generic):
        return value.item()
    return value


FRACTIONS = ("efficiency", "utilisation")  # shares, 0..1, as in the study tables


def kpi_range(name: str) -> tuple[float, float, str]:
    """The values a measured KPI can take: (low, high, in words)."""
    if name == "gripping_rate":
        return 0.0, 100.0, "a percentage 0..100"
    if name in FRACTIONS or name.endswith("_utilisation"):
        return 0.0, 1.0, "a share 0..1 (85 % is 0.85)"
    return 0.0, math.inf, "a number >= 0"


def robot_of(name: str) -> int | None:
    """The robot (1-based) a per-robot KPI column names (``r2_throughput`` -> 2), else None."""
    m = ROBOT_KPI.match(name)
    return int(m.group(1)) if m else None


def _header(path: Path, text: str) -> None:
    """Refuse a header that names a column twice (pandas would rename it silently)."""
    for n, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        names = [c.strip() for c in next(csv.reader([line]), [])]
        seen: set[str] = set()
        for c in names:
            if c in seen:
                raise StudyError(
                    f"--targets {path}: line {n}: the header names column '{clip(c, 40)}' "
                    "twice; give each column once"
                )
            seen.add(c)
        return


def _read(path: Path) -> pd.DataFrame:
    if not path.exists() and not path.is_symlink():
        raise StudyError(f"--targets: no file '{path}'")
    text = read_user_text(path, f"--targets {path}", TARGETS_BYTES, StudyError)
    _header(path, text)
    try:
        frame = pd.read_csv(io.StringIO(text), comment="#", skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise StudyError(
            f"--targets {path}: is empty; give a header row and a row per point"
        ) from None
    except (pd.errors.ParserError, UnicodeDecodeError) as e:
        first = str(e).strip().splitlines()[0]
        raise StudyError(f"--targets {path}: not a readable CSV: {first}") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    if len(frame) == 0:
        raise StudyError(f"--targets {path}: has a header but no points; give a row per point")
    return frame


def _kpi_column(path: Path, frame: pd.DataFrame, name: str) -> np.ndarray:
    values = pd.to_numeric(frame[name], errors="coerce")
    bad = values.isna() & frame[name].notna()
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        raise StudyError(
            f"--targets {path}: row {row + 1}, column {name}: {frame[name].iloc[row]!r} is not "
            f"a number"
        )
    return values.to_numpy(dtype=float)


def read_targets(path: str | Path) -> Targets:
    """Read and check a targets CSV (module docstring); mistakes are one-line StudyErrors."""
    p = Path(path)
    frame = _read(p)
    kpis = [c for c in frame.columns if is_kpi(c)]
    if not kpis:
        raise StudyError(
            f"--targets {p}: no KPI column; add at least gripping_rate (or one of "
            f"{', '.join(LINE_KPIS)}, r<i>_throughput, r<i>_picks)"
        )
    varied = []
    for c in frame.columns:
        if c == WEIGHT or c in kpis:
            continue
        try:
            varied.append(resolve_path(c, f"--targets {p}: column"))
        except StudyError as e:
            raise StudyError(f"{e}; or name a KPI ({', '.join(LINE_KPIS)}, r<i>_picks)") from None
    target = np.column_stack([_kpi_column(p, frame, k) for k in kpis])
    for j, k in enumerate(kpis):
        low, high, words = kpi_range(k)
        col = target[:, j]
        bad = np.flatnonzero(~np.isnan(col) & ~(np.isfinite(col) & (col >= low) & (col <= high)))
        if len(bad):
            i = int(bad[0])
            raise StudyError(
                f"--targets {p}: row {i + 1}, column {k}: {target[i, j]:g} is not allowed; "
                f"give {words}"
            )
    for i, row in enumerate(target):
        if np.all(np.isnan(row)):
            raise StudyError(f"--targets {p}: row {i + 1} has no KPI value; fill at least one")
    weight = np.ones(len(frame))
    if WEIGHT in frame.columns:
        weight = _kpi_column(p, frame, WEIGHT)
        bad = np.flatnonzero(~((weight >= 0) & np.isfinite(weight)))
        if len(bad):
            raise StudyError(
                f"--targets {p}: row {bad[0] + 1}, column weight: {weight[bad[0]]} is not "
                f"allowed; give a finite number >= 0"
            )
        if not weight.sum() > 0:
            raise StudyError(
                f"--targets {p}: column weight: every row's weight is 0, so no point counts "
                "and nothing can be fitted; give at least one row a weight above 0"
            )
    values = []
    for i in range(len(frame)):
        cells = []
        for ref in varied:
            v = _cell(frame[ref.path].iloc[i])
            if v is None or (isinstance(v, float) and math.isnan(v)):
                raise StudyError(f"--targets {p}: row {i + 1}, column {ref.path}: empty")
            cells.append(v)
        values.append(tuple(cells))
    return Targets(str(p), tuple(varied), tuple(kpis), tuple(values), target, weight)
