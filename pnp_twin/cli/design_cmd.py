"""The ``design`` command of ``pnp-twin``: the cheapest configuration whose gripping rate
meets a target with a confidence that holds after the selection
(``pnp_twin.studies.design``). It prints the answer (or one JSON object with ``--json``:
``choice``, ``gripping_rate``, ``ci_low``, ``total_cost``, ``alternatives``) and writes
``design.json`` and ``report.html`` into ``--out``. Asking again with another target,
confidence or cost file reuses every journalled run (``DIR/evals/``).
"""

from __future__ import annotations

import os
import textwrap
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
from pnp_twin.cli.claim import check_folder, inputs_of
from pnp_twin.cli.console import note
from pnp_twin.cli.decision_opts import (
    AcrossOpt,
    BaselineOpt,
    RayAddressOpt,
    RayBackendOpt,
    WriteScenarioOpt,
    executor,
)
from pnp_twin.cli.study_folder import check_policies, run_locked
from pnp_twin.studies.deploy import check_scenario_out, scenario_file_text, write_scenario_file
from pnp_twin.studies.design import check_baseline, check_design, run_design
from pnp_twin.studies.kpi_choice import parse_kpi
from pnp_twin.twin.budget import check_study
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.output import dumps_json
from pnp_twin.twin.trace import trace_files


@app.command("design")
def design_cmd(
    scenario: ScenarioArg,
    target: Annotated[float, typer.Option("--target", help="Target gripping rate in %.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder (rerun to reuse).")],
    vary: Annotated[
        list[str] | None,
        typer.Option(
            "--vary",
            help="PATH=LO:HI (whole numbers), PATH=V1,V2,... or PATH=2.0:6.0 (continuous: "
            "a bound with a decimal point; searched by optuna). Repeatable.",
        ),
    ] = None,
    policy: Annotated[
        list[str] | None, typer.Option("--policy", "-p", help="Rule to consider (repeatable).")
    ] = None,
    costs: Annotated[
        Path | None,
        typer.Option("--costs", help="Cost TOML: robot_price, belt_price, lost_part_cost, hours."),
    ] = None,
    confidence: Annotated[float, typer.Option("--confidence", help="Confidence level.")] = 0.95,
    replications: Annotated[
        int, typer.Option("--replications", "-r", help="First replications everywhere.")
    ] = 3,
    max_replications: Annotated[
        int, typer.Option("--max-replications", help="Most replications where still open.")
    ] = 24,
    trials: Annotated[
        int,
        typer.Option("--trials", help="Points optuna evaluates per discrete combination."),
    ] = 30,
    sets: SetOpt = None,
    workers: WorkersOpt = None,
    engine: EngineOpt = Engine.auto,
    no_report: NoReportOpt = False,
    json_out: JsonOpt = False,
    kpi: KpiOpt = "gripping_rate",
    force: ForceOpt = False,
    across: AcrossOpt = None,
    baseline: BaselineOpt = None,
    write_scenario: WriteScenarioOpt = None,
    backend: RayBackendOpt = "local",
    address: RayAddressOpt = None,
) -> None:
    """The cheapest configuration meeting a target gripping rate with a confidence."""
    sc = load_scenario(scenario, parse_sets(sets or []))
    figure = parse_kpi(kpi, sc)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: is a file; give a folder")
    if not vary and not policy:
        raise UserError("--vary: give at least one field to vary, e.g. --vary robots.count=3:8")
    traces = len(trace_files(sc))
    capped = traces > 1 and max_replications > traces  # trace k in replication k: each once
    if capped:
        max_replications, replications = traces, min(replications, traces)
    check_design(
        sc,
        target,
        vary or [],
        costs,
        confidence,
        replications,
        max_replications,
        trials,
        across or [],
    )  # every mistake is one line before the folder exists
    check_policies(policy or [sc.policy], sc.robots.count)
    check_study(sc, {}, len(policy or [sc.policy]), max_replications, force)  # work limit
    inputs = inputs_of(scenario, sc, costs=costs, policy=policy, baseline=baseline)
    today = check_baseline(baseline, costs, sc, across or [])
    if write_scenario is not None:
        check_scenario_out(write_scenario, inputs, "--write-scenario")
    runner = executor(backend, workers or (os.cpu_count() or 1), address)
    check_folder(out, "design", inputs)  # claimed below; checked now, before any note
    if capped:  # said once everything is checked: a refusal stays one line
        note(f"feeder.trace: {traces} traces, so at most {traces} replications (trace k each)")
    with runner:
        result = run_locked(
            out,
            "design",
            inputs,
            lambda cmd: run_design(
                sc,
                out,
                target,
                vary or [],
                policy,
                costs,
                confidence,
                replications,
                max_replications,
                workers or (os.cpu_count() or 1),
                engine.value,
                cmd,
                trials=trials,
                kpi=figure,
                across=across or [],
                baseline=today,
                executor=runner,
            ),
        )
    if write_scenario is not None and result["choice"] is not None:
        text = scenario_file_text(
            result["scenario_chosen"],
            result["choice"]["policy"],
            result["seeds"],
            result["command"],
            textwrap.wrap(result["text"], 96),
            sc.source_dir,
        )
        note(f"scenario: {write_scenario_file(write_scenario, text)}")
    elif write_scenario is not None:
        note(f"--write-scenario: nothing written to {write_scenario}: no configuration meets it")
    if not no_report:
        from pnp_twin.reports.design import build_design_report

        note(f"report: {build_design_report(out)}")
    if json_out:
        keep = ("scenario", "scenario_chosen", "rows")
        typer.echo(dumps_json({k: v for k, v in result.items() if k not in keep}, indent=2))
        return
    typer.echo(result["text"])
    note(
        f"{result['runs']} runs of the {result['runs_fixed']} a fixed {max_replications} "
        f"replications would take ({result['runs_simulated']} simulated now)"
    )
