"""Options the decision commands share (``design``, ``size``, ``tune``, ``capacity``,
``headroom``): conditions to meet the target at, today's line, the chosen line as a
scenario file, and where the runs execute."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from pnp_twin.studies.backends import Executor

AcrossOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--across",
        help="PATH=V1,V2,...: a condition the choice must meet the target at, every value at "
        "once (e.g. feeder.rate=6,7,8; feeder.trace=DIR: each shift's trace). Repeatable.",
    ),
]
BaselineOpt = Annotated[
    Path | None,
    typer.Option(
        "--baseline",
        help="Today's line as a scenario file: the saving a year and the payback months.",
    ),
]
WriteScenarioOpt = Annotated[
    Path | None,
    typer.Option(
        "--write-scenario",
        metavar="FILE",
        help="Write the chosen line as a scenario file (.toml) that `pnp-twin run` reproduces.",
    ),
]
RayBackendOpt = Annotated[
    str,
    typer.Option("--backend", help="Where runs execute: local (a process pool) or ray."),
]
RayAddressOpt = Annotated[
    str | None,
    typer.Option("--address", help="Ray cluster address (default RAY_ADDRESS, else a local Ray)."),
]


def executor(backend: str, workers: int, address: str | None) -> Executor:
    """The study's one executor (checked here: a bad backend or worker count is one line)."""
    if address is not None and backend != "ray":
        from pnp_twin.studies.plan import StudyError

        raise StudyError("--address: only with --backend ray")
    return Executor(backend, workers, address)
