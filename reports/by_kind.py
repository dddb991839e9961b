"""The report of a folder by the kind of command that wrote it (``design``, ``capacity``,
``calibrate``, ``headroom``, ``tune``): ``pnp-twin report DIR`` rebuilds any of them from the
folder's own files, as the command itself wrote it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from pnp_twin.reports.load import read_json
from pnp_twin.twin.folder_kind import folder_kind
from pnp_twin.twin.output import write_text


def _headroom(folder: Path, out: Path) -> Path:
    from pnp_twin.reports.headroom_report import headroom_html

    return write_text(headroom_html(read_json(folder / "headroom.json")), out)


def _tune(folder: Path, out: Path) -> Path:
    import pandas as pd

    from pnp_twin.reports.tune_report import tune_html

    data = read_json(folder / "tune.json")
    trials = pd.read_csv(folder / "trials.csv").to_dict("records")
    return write_text(tune_html(data, trials), out)


def _design(folder: Path, out: Path) -> Path:
    from pnp_twin.reports.design import build_design_report

    return build_design_report(folder, out)


def _capacity(folder: Path, out: Path) -> Path:
    from pnp_twin.reports.capacity import build_capacity_report

    return build_capacity_report(folder, out)


def _calibrate(folder: Path, out: Path) -> Path:
    from pnp_twin.reports.calibration import build_calibration_report

    return build_calibration_report(folder, out)


BUILDERS: dict[str, Callable[[Path, Path], Path]] = {
    "design": _design,
    "capacity": _capacity,
    "calibrate": _calibrate,
    "headroom": _headroom,
    "tune": _tune,
}


def build_by_kind(folder: Path, out: Path | None) -> Path | None:
    """The report of a folder of one of :data:`BUILDERS`' kinds written to ``out`` (default
    ``folder/report.html``); None for any other folder (a sweep, size or mix study)."""
    builder = BUILDERS.get(folder_kind(folder) or "")
    if builder is None:
        return None
    return builder(folder, out if out is not None else folder / "report.html")
