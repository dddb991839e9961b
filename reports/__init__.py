"""Reports: one self-contained HTML page per study folder, built from its tables only.

``build_report(DIR)`` reads the folder (``docs/study_format.md``), draws the figures and
writes ``DIR/report.html`` atomically. A training run folder (``pnp-twin train``), or a
folder holding several, gets the training report (``reports.training``) instead. No
simulation happens here.
"""

from __future__ import annotations

import logging
from pathlib import Path

from pnp_twin.reports.by_kind import build_by_kind
from pnp_twin.reports.html import render
from pnp_twin.reports.layout import build_page
from pnp_twin.reports.load import ReportError, Study, load_study
from pnp_twin.reports.record_figures import Animation
from pnp_twin.reports.training import build_training_page
from pnp_twin.reports.training_load import is_training_folder, load_runs
from pnp_twin.twin.output import write_text

log = logging.getLogger(__name__)

__all__ = ["Animation", "ReportError", "Study", "build_report", "load_study", "render_report"]


def render_report(study_dir: Path | str, animation: Animation | None = None) -> str:
    """The report of the study (or training run(s)) in ``study_dir`` as one HTML string."""
    if is_training_folder(study_dir):
        return render(build_training_page(load_runs(study_dir)))
    return render(build_page(load_study(study_dir), animation))


def build_report(
    study_dir: Path | str, out: Path | str | None = None, animation: Animation | None = None
) -> Path:
    """Write the report of ``study_dir`` to ``out`` (default ``study_dir/report.html``)."""
    study_dir = Path(study_dir)
    built = build_by_kind(study_dir, Path(out) if out is not None else None)
    if built is not None:  # a design, capacity, calibration, headroom or tune folder
        return built
    target = Path(out) if out is not None else study_dir / "report.html"
    page = render_report(study_dir, animation)
    if not target.parent.is_dir():
        raise ReportError(f"--out {target}: folder {target.parent} does not exist")
    write_text(page, target)
    log.info("report written to %s (%.1f MB)", target, len(page) / 1e6)
    return target
