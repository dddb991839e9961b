"""The ``export`` command of ``pnp-twin``: a study folder as an Excel workbook.

``pnp-twin export DIR --xlsx FILE`` writes the folder's results, summary, paired and best
tables as sheets of FILE, units in the headers (``pnp_twin.studies.export``), and the runs
of a folder's runs store (``design``, ``capacity``, ``calibrate``, ``headroom``). Nothing is
simulated; a folder that is not a study ends with a one-line error and exit code 2.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from pnp_twin.cli.app import app
from pnp_twin.studies.export import export_xlsx
from pnp_twin.twin.errors import UserError


@app.command("export")
def export(
    study_dir: Annotated[
        Path,
        typer.Argument(
            metavar="DIR",
            help="A study folder (sweep, size, mix; design, capacity, calibrate, headroom).",
            show_default=False,
        ),
    ],
    xlsx: Annotated[
        Path | None,
        typer.Option("--xlsx", metavar="FILE", help="Write the tables to FILE (.xlsx) as sheets."),
    ] = None,
) -> None:
    """Export a study's tables (results, summary, paired, best) with units in the headers."""
    if xlsx is None:
        raise UserError("export: give --xlsx FILE.xlsx")
    if xlsx.is_dir():
        raise UserError(f"--xlsx {xlsx}: is a folder; give a file name such as {xlsx}/study.xlsx")
    sheets = export_xlsx(study_dir, xlsx)
    rows = ", ".join(f"{name} {n} rows" for name, n in sheets.items())
    typer.echo(f"wrote {xlsx}: {rows}", err=True)
