"""The ``tune`` command of ``pnp-twin``: the settings of a controller's balancing mode.

Runs :func:`pnp_twin.studies.tune.run_tune` and writes ``tune.json``, ``trials.csv`` and
``report.html`` into ``--out`` (under the folder's study lock, each file written atomically);
prints the answer, the line to type into the controller, or the JSON with ``--json``.
"""

from __future__ import annotations

import shlex
import sys
import textwrap
from pathlib import Path
from typing import Annotated

import typer

from pnp_twin.cli.app import (
    Engine,
    EngineOpt,
    ForceOpt,
    JsonOpt,
    ProcessesOpt,
    RunDurationOpt,
    ScenarioArg,
    SetOpt,
    app,
)
from pnp_twin.cli.claim import inputs_of
from pnp_twin.cli.console import note
from pnp_twin.cli.decision_opts import WriteScenarioOpt
from pnp_twin.cli.study_folder import run_locked, with_duration
from pnp_twin.studies.deploy import check_scenario_out, scenario_file_text, write_scenario_file
from pnp_twin.studies.tune import Tuned, TuneSettings, check_tune
from pnp_twin.twin.budget import check_study
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.output import dumps_json


@app.command("tune")
def tune(
    scenario: ScenarioArg,
    out: Annotated[
        Path,
        typer.Option(
            "--out", metavar="DIR", help="The study folder (created).", show_default=False
        ),
    ],
    strategy: Annotated[
        str, typer.Option("--strategy", help="The balancing mode to tune: share or lane.")
    ] = "share",
    rule: Annotated[
        str, typer.Option("--rule", help="The order within what each robot owns.")
    ] = "FIFO",
    target: Annotated[
        float | None,
        typer.Option(
            "--target",
            help="Gripping rate to reach, %; then the fewest parts passed on between robots "
            "(default: the highest G).",
        ),
    ] = None,
    trials: Annotated[
        int, typer.Option("--trials", min=1, max=10_000, help="Settings the optimiser tries.")
    ] = 40,
    tuning_seeds: Annotated[
        int, typer.Option("--tuning-seeds", min=1, max=1000, help="Seeds each trial runs.")
    ] = 4,
    seeds: Annotated[
        int,
        typer.Option("--seeds", min=2, max=10_000, help="Fresh seeds the answer is measured on."),
    ] = 10,
    release: Annotated[
        bool,
        typer.Option(
            "--release/--lost",
            help="A part its owner misses goes on to the robots downstream (or is lost).",
        ),
    ] = False,
    duration: RunDurationOpt = None,
    sets: SetOpt = None,
    workers: ProcessesOpt = 1,
    engine: EngineOpt = Engine.fast,
    as_json: JsonOpt = False,
    force: ForceOpt = False,
    write_scenario: WriteScenarioOpt = None,
) -> None:
    """The settings of a controller's balancing mode (share or lane) that maximise G, or meet
    a target with the fewest parts passed on: the line to type into the controller."""
    sc = load_scenario(scenario, parse_sets(sets or []))
    sc = with_duration(sc, duration)
    settings = TuneSettings(
        strategy=strategy.strip().lower(),
        rule=rule.strip().upper(),
        target=target,
        trials=trials,
        tuning_seeds=tuning_seeds,
        seeds=seeds,
        release=release,
        engine=engine.value,
        workers=workers,
    )
    check_tune(sc, settings)  # everything refusable before the folder is made
    check_study(sc, {}, trials + 2, seeds + tuning_seeds, force)  # work limit
    inputs = inputs_of(scenario, sc)
    if write_scenario is not None:
        check_scenario_out(write_scenario, inputs, "--write-scenario")
    from pnp_twin.studies.tune import run_tune

    def work(_: str) -> Tuned:
        result = run_tune(sc, settings, _progress)
        write_tune(result, out)
        return result

    result = run_locked(out, "tune", inputs, work)
    if write_scenario is not None:
        text = scenario_file_text(
            sc.model_dump(mode="json"),
            result.best.name,
            settings.seed_list,
            shlex.join(["pnp-twin", *sys.argv[1:]]),
            textwrap.wrap(result.answer(), 96),
            sc.source_dir,
        )
        note(f"scenario: {write_scenario_file(write_scenario, text)}")
    if as_json:
        typer.echo(dumps_json(result.to_json(), indent=2))
        return
    typer.echo(result.answer())
    note(f"wrote {out}/tune.json, trials.csv, report.html")


def write_tune(result: Tuned, out: Path) -> None:
    """The study's files, each written atomically."""
    import pandas as pd

    from pnp_twin.reports.tune_report import tune_html
    from pnp_twin.twin.output import write_json, write_table, write_text

    data = result.to_json()
    write_table(pd.DataFrame(result.trials), out / "trials.csv")
    write_text(tune_html(data, result.trials), out / "report.html")
    write_json(data, out / "tune.json")  # last: a folder with it holds a finished study


def _progress(stage: str, done: int, total: int) -> None:
    if total and (done == total or done % 10 == 0):
        note(f"{stage}: {done} of {total}")
