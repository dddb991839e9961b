"""The ``capacity`` command of ``pnp-twin``: the highest part flow a line sustains at a
target gripping rate (``pnp_twin.studies.capacity``), with its interval, by root finding
over common random numbers. It prints the answer (or one JSON object with ``--json``:
``max_rate``, ``ci_low``, ``ci_high``, ...) and writes ``capacity.json`` and ``report.html``
into ``--out``. Asking again with another ``--target`` or ``--confidence`` replays the flows
already simulated (``DIR/evals/``) and simulates only the new ones.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from pnp_twin.cli.app import (
    Engine,
    EngineOpt,
    ForceOpt,
    JsonOpt,
    KpiOpt,
    NoReportOpt,
    ScenarioArg,
    SetOpt,
    WorkersOpt,
    app,
)
from pnp_twin.cli.claim import inputs_of
from pnp_twin.cli.console import note
from pnp_twin.cli.decision_opts import RayAddressOpt, RayBackendOpt, executor
from pnp_twin.cli.study_folder import check_policies, run_locked
from pnp_twin.studies.calibrate_eval import EVALS
from pnp_twin.studies.capacity import (
    AUTO_FIRST,
    AUTO_MOST,
    GAP,
    check_capacity,
    parse_replications,
    run_capacity,
)
from pnp_twin.studies.kpi_choice import parse_kpi
from pnp_twin.twin.budget import check_study
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.output import dumps_json


@app.command("capacity")
def capacity_cmd(
    scenario: ScenarioArg,
    target: Annotated[float, typer.Option("--target", help="Target gripping rate in %.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder (rerun to reuse).")],
    confidence: Annotated[float, typer.Option("--confidence", help="Confidence level.")] = 0.95,
    policy: Annotated[
        list[str] | None,
        typer.Option("--policy", "-p", help="Rule to run (repeatable: the best is picked)."),
    ] = None,
    replications: Annotated[
        str,
        typer.Option(
            "--replications",
            "-r",
            help="Replications per flow, or auto: doubled from 5 until the promise is within "
            "--gap of the mean crossing.",
        ),
    ] = "5",
    gap: Annotated[
        float,
        typer.Option(
            "--gap",
            help="With -r auto: the promise's largest gap below the mean "
            "crossing, as a share (0.05 = 5 %).",
        ),
    ] = GAP,
    max_replications: Annotated[
        int, typer.Option("--max-replications", help="With -r auto: at most this many.")
    ] = AUTO_MOST,
    vary: Annotated[
        list[str] | None,
        typer.Option(
            "--vary",
            help="PATH=LO:HI (whole numbers) or PATH=V1,V2,...: one search per combination "
            "(repeatable).",
        ),
    ] = None,
    start: Annotated[
        float | None, typer.Option("--start", help="First flow tried, parts/s (feeder.rate).")
    ] = None,
    sets: SetOpt = None,
    workers: WorkersOpt = None,
    engine: EngineOpt = Engine.auto,
    no_report: NoReportOpt = False,
    json_out: JsonOpt = False,
    kpi: KpiOpt = "gripping_rate",
    force: ForceOpt = False,
    backend: RayBackendOpt = "local",
    address: RayAddressOpt = None,
) -> None:
    """The highest part flow the line sustains at a target gripping rate, with its interval."""
    sc = load_scenario(scenario, parse_sets(sets or []))
    figure = parse_kpi(kpi, sc)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: is a file; give a folder")
    reps = parse_replications(replications)
    first = AUTO_FIRST if reps == "auto" else int(reps)
    check_capacity(sc, target, confidence, first, vary or [], start, gap, max_replications)
    check_policies(policy or [sc.policy], sc.robots.count)  # all before the folder exists
    most = max_replications if reps == "auto" else first
    check_study(sc, {}, len(policy or [sc.policy]), most, force)  # work limit
    n_workers = workers or (os.cpu_count() or 1)
    with executor(backend, n_workers, address) as runner:
        result = run_locked(
            out,
            "capacity",
            inputs_of(scenario, sc, policy=policy),
            lambda cmd: run_capacity(
                sc,
                out,
                target,
                confidence,
                policy,
                reps,
                n_workers,
                engine.value,
                start,
                cmd,
                vary=vary or [],
                kpi=figure,
                executor=runner,
                gap=gap,
                most=max_replications,
            ),
        )
    if not no_report:
        from pnp_twin.reports.capacity import build_capacity_report

        note(f"report: {build_capacity_report(out)}")
    if json_out:
        keep = ("scenario", "curve", "seeds")
        data = {k: v for k, v in result.items() if k not in keep}
        if "configurations" in data:
            data["configurations"] = [
                {k: v for k, v in c.items() if k != "curve"} for c in data["configurations"]
            ]
        typer.echo(dumps_json(data, indent=2))
        return
    for c in result.get("configurations") or [result]:
        typer.echo(c["text"])
    note(
        f"{result['flows_evaluated']} flows evaluated with {result['replications']} replications "
        f"each: {result['runs_simulated']} runs simulated, {result['runs_replayed']} replayed "
        f"from {out / EVALS}"
    )
