"""The ``compare`` command of ``pnp-twin``: two policies on one scenario and one seed.

Both runs see the same parts (common random numbers); the command prints their gripping
rates, the difference and how many parts one grips that the other loses, and with
``--report`` writes a page replaying both runs in step (:mod:`reports.compare_report`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich import box
from rich.table import Table

from pnp_twin.cli.app import ScenarioArg, SetOpt, app
from pnp_twin.cli.claim import check_output_file, inputs_of
from pnp_twin.cli.console import note, stdout_console
from pnp_twin.policies import make_policy
from pnp_twin.twin.budget import check_run
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.output import OutputError, check_writable
from pnp_twin.twin.run import simulate


@app.command("compare")
def compare(
    scenario: ScenarioArg,
    policies: Annotated[
        list[str] | None,
        typer.Option(
            "--policy",
            "-p",
            metavar="NAME|MIX",
            help="A policy, as for run; give exactly two (-p SD -p lookahead).",
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option("--seed", min=0, metavar="N", help="Master seed; default the scenario's."),
    ] = None,
    sets: SetOpt = None,
    report: Annotated[
        Path | None,
        typer.Option(
            "--report",
            metavar="FILE",
            help="Write an HTML page replaying both runs in step to FILE.",
        ),
    ] = None,
    replay_window: Annotated[
        float,
        typer.Option(
            "--replay-window",
            min=1.0,
            max=3600.0,
            metavar="SECONDS",
            help="How much of the runs the replay shows, from the end of the warm-up.",
        ),
    ] = 60.0,
    force: Annotated[
        bool, typer.Option("--force", help="Run even above the work limit (twin.budget).")
    ] = False,
) -> None:
    """Run SCENARIO under two policies with one seed and show where they differ."""
    names = list(policies or [])
    if len(names) != 2:
        raise UserError(
            f"--policy: give exactly two policies (got {len(names)}), e.g. -p SD -p lookahead"
        )
    if report is not None:
        if report.suffix.lower() not in (".html", ".htm"):
            raise OutputError(f"--report: '{report}' must end in .html")
        check_writable(report, "--report")
    scn = load_scenario(scenario, parse_sets(sets or []))
    if report is not None:
        check_output_file(report, "--report", inputs_of(scenario, scn, policy=names))
    check_run(scn, force)
    pols = [make_policy(name, scn.robots.count) for name in names]  # both checked first
    from pnp_twin.reports.compare_report import (  # the front end imports reports
        RunRecords,
        build_compare_report,
        swapped_parts,
    )

    runs = []
    for name, pol in zip(names, pols, strict=True):
        note(f"simulating {scn.name} with {name}...")
        result = simulate(scn, pol, seed=seed)
        runs.append(RunRecords(result.kpis, result.parts, result.spans))
    a, b = runs
    a_only, b_only = swapped_parts(a.parts, b.parts, scn.warmup)
    t = Table(
        title=f"{scn.name}: seed {a.kpis['seed']}, parts fed in [{scn.warmup:g}, "
        f"{scn.duration:g}) s",
        box=box.SIMPLE_HEAVY,
    )
    for col in ("policy", "G (%)", "picked", "lost", "grips, the other loses"):
        t.add_column(col, justify="right")
    for run, only in ((a, a_only), (b, b_only)):
        k = run.kpis
        t.add_row(
            str(k["policy"]),
            f"{k['gripping_rate']:.2f}",
            str(k["parts_picked"]),
            str(k["parts_missed"]),
            str(only),
        )
    stdout_console().print(t)
    diff = float(b.kpis["gripping_rate"]) - float(a.kpis["gripping_rate"])
    note(f"{b.kpis['policy']} - {a.kpis['policy']}: {diff:+.2f} points of G (one seed)")
    if report is not None:
        from pnp_twin.reports.record_figures import Animation

        build_compare_report(
            runs, scn.model_dump(mode="json"), report, Animation(seconds=replay_window)
        )
        note(f"report: {report}")
