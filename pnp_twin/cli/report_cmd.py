"""The ``report`` command of ``pnp-twin``: (re)build the HTML report of a study folder.

``pnp-twin report DIR`` reads the folder's tables (``docs/study_format.md``) and writes
``DIR/report.html``; ``--out FILE`` writes it elsewhere. Nothing is simulated. A folder that
is not a study, or an unwritable ``--out``, ends with a one-line error and exit code 2.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from pnp_twin.cli.app import app
from pnp_twin.twin.errors import UserError


@app.command("report")
def report(
    study_dir: Annotated[
        Path,
        typer.Argument(
            metavar="DIR",
            help="A study folder (sweep, size, mix), a training run, or a folder of runs.",
            show_default=False,
        ),
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="Write the report here (default DIR/report.html).",
            show_default=False,
        ),
    ] = None,
    animate_from: Annotated[
        float | None,
        typer.Option(
            "--animate-from",
            min=0.0,
            help="Start of the belt animation, s of the recorded run (default: end of warm-up).",
            show_default=False,
        ),
    ] = None,
    animate_seconds: Annotated[
        float,
        typer.Option("--animate-seconds", min=0.2, max=3600.0, help="Length of the animation, s."),
    ] = 60.0,
) -> None:
    """Build the self-contained HTML report of a study or training folder (opens offline)."""
    if out is not None and out.is_dir():
        raise UserError(f"--out {out}: is a folder; give a file name such as {out}/report.html")
    if out is not None and out.suffix.lower() not in (".html", ".htm"):
        raise UserError(
            f"--out {out}: must end in .html (a report never replaces a table or a study file)"
        )
    from pnp_twin.reports import Animation, build_report  # the front end imports reports

    path = build_report(study_dir, out, Animation(animate_from, animate_seconds))
    typer.echo(f"report: {path}", err=True)
