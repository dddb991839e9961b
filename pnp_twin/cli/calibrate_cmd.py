"""The ``calibrate`` command of ``pnp-twin``: fit a scenario's unknowns to measured points.

It fits (``pnp_twin.studies.calibrate``) with a progress bar on stderr (evaluations, best
objective so far), writes the calibrated scenario file and tables into ``--out``
(``calibrate_output``) and the HTML report (``reports.calibration``), and prints the points
table, or one JSON object with ``--json``. Re-running the same command resumes from the
folder's journal without simulating again.
"""

from __future__ import annotations

import math
import os
import shlex
import shutil
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from pnp_twin.cli.app import (
    Engine,
    EngineOpt,
    ForceOpt,
    FreshOpt,
    JsonOpt,
    NoReportOpt,
    ScenarioArg,
    SetOpt,
    WorkersOpt,
    app,
)
from pnp_twin.cli.claim import claim_folder, inputs_of
from pnp_twin.policies import RULES
from pnp_twin.studies.calibrate import Problem, calibrate, check_problem
from pnp_twin.studies.calibrate_eval import EVALS
from pnp_twin.studies.calibrate_fields import apply_values, check_distinct, parse_fit
from pnp_twin.studies.calibrate_output import write_outputs
from pnp_twin.studies.calibrate_targets import read_targets
from pnp_twin.studies.plan import StudyError
from pnp_twin.twin import budget
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.output import dumps_json


@contextmanager
def _journal(out: Path, fresh: bool) -> Iterator[None]:
    """With ``fresh``, the old journal is moved aside and deleted only once the new fit has
    finished; a failed fit puts it back."""
    old, aside = out / EVALS, out / f".{EVALS}.replaced"
    moved = fresh and old.is_dir()
    if moved:
        shutil.rmtree(aside, ignore_errors=True)
        old.rename(aside)
    try:
        yield
    except BaseException:
        if moved:
            shutil.rmtree(old, ignore_errors=True)
            aside.rename(old)
        raise
    if moved:
        shutil.rmtree(aside, ignore_errors=True)


def _problem(
    scenario: str,
    targets: Path,
    fits: list[str],
    sets: list[str] | None,
    policy: list[str] | None,
    replications: int,
    max_evals: int,
    profile: int,
    pairs: int,
) -> tuple[Problem, dict[str, Any]]:
    overrides = parse_sets(sets or [])
    sc = load_scenario(scenario, overrides)
    if not fits:
        raise StudyError("--fit: give at least one field to fit, e.g. --fit robots.pick_time=0:0.2")
    params = [parse_fit(f) for f in fits]
    t = read_targets(targets)
    check_distinct(params, list(t.varied))
    policies = tuple(policy) if policy else tuple(RULES)
    problem = Problem(sc, t, tuple(params), policies, replications, max_evals, profile, pairs)
    check_problem(problem)  # before the progress bar: a mistake is one line on its own
    return problem, overrides


def _check_work(problem: Problem, force: bool) -> None:
    """The fit's work within :mod:`twin.budget`'s limits unless --force: at most
    MAX_RUNS runs (evaluations, profiles and pair grids, at every point, with every policy
    and replication), none of them above MAX_PARTS parts."""
    t, k = problem.targets, len(problem.params)
    evals = problem.max_evals + problem.profile * k + problem.pairs**2 * (k * (k - 1) // 2)
    runs = evals * t.n * len(problem.policies) * problem.replications
    if runs > budget.MAX_RUNS and not force:
        raise budget.BudgetError(
            f"--replications: the fit may simulate {runs:,} runs ({evals} evaluations x {t.n} "
            f"points x {len(problem.policies)} policies x {problem.replications} replications), "
            f"above the limit of {budget.MAX_RUNS:,}; lower --max-evals, --profile, --pairs or "
            f"--replications, {budget.FORCE}"
        )
    for i in range(t.n):
        values = {**t.point(i), **problem.values(problem.start().tolist())}
        budget.check_run(apply_values(problem.scenario, values), force)


def _points_table(info: dict[str, Any]) -> Table:
    t = Table(title="Measured vs predicted (95 % CI)", box=box.SIMPLE)
    for c in ["point", *info["varied"], "KPI", "measured", "predicted", "residual", "policy"]:
        t.add_column(c, justify="left" if c in ("KPI", "policy") else "right")
    for r in info["points"]:
        ci = "" if r["ci_low"] is None else f" [{r['ci_low']:.2f}, {r['ci_high']:.2f}]"
        t.add_row(
            str(r["point"]),
            *(str(r[v]) for v in info["varied"]),
            r["kpi"],
            f"{r['target']:.4g}",
            f"{r['predicted']:.2f}{ci}",
            f"{r['residual']:+.2f}",
            r["policy"],
        )
    return t


def _fitted_table(info: dict[str, Any]) -> Table:
    t = Table(title=f"Fitted (objective {info['objective']:.4g})", box=box.SIMPLE)
    plus = f"{float(info.get('near_optimal_margin') or 1.0):.3g}"
    for c in ("field", "bounds", "start", "fitted", f"objective within +{plus} for"):
        t.add_column(c, justify="left" if c == "field" else "right")
    for q in info["params"]:
        lo, hi = q["near_optimal"]
        span = "" if lo is None or math.isnan(lo) else f"{lo:.4g} .. {hi:.4g}"
        t.add_row(
            q["name"],
            f"{q['low']:g} .. {q['high']:g}",
            f"{q['start']:.4g}",
            f"{q['value']:.4g}",
            span,
        )
    return t


def _write_report(out: Path, err: Console) -> None:
    try:
        from pnp_twin.reports.calibration import build_calibration_report
    except ImportError as e:  # plotly missing: the tables are still there
        err.print(f"note: report not written ({e})")
        return
    err.print(f"report: {build_calibration_report(out)}")


@app.command("calibrate")
def calibrate_cmd(
    scenario: ScenarioArg,
    targets: Annotated[
        Path,
        typer.Option(
            "--targets",
            "-t",
            help="CSV of measured points (fields, KPIs, weight).",
            show_default=False,
        ),
    ],
    out: Annotated[
        Path,
        typer.Option("--out", "-o", help="Output folder (rerun to resume).", show_default=False),
    ],
    fit: Annotated[
        list[str] | None,
        typer.Option(
            "--fit",
            metavar="PATH=LO:HI",
            help="A numeric field to fit with its bounds, e.g. robots.bin_offset.1=0.2:0.8"
            "; PATH,PATH=LO:HI fits fields sharing one value (repeatable).",
        ),
    ] = None,
    policy: Annotated[
        list[str] | None,
        typer.Option(
            "--policy",
            "-p",
            help="Policy (repeatable); the prediction is the best of "
            "them at each point. Default: every rule.",
        ),
    ] = None,
    replications: Annotated[
        int,
        typer.Option(
            "--replications", "-r", min=1, max=10_000, help="Common-random-number replications."
        ),
    ] = 5,
    max_evals: Annotated[
        int, typer.Option("--max-evals", min=1, max=100_000, help="Optimiser evaluations at most.")
    ] = 60,
    profile: Annotated[
        int,
        typer.Option("--profile", min=0, max=1000, help="Profile points per parameter (0: none)."),
    ] = 7,
    pairs: Annotated[
        int,
        typer.Option(
            "--pairs",
            min=0,
            max=100,
            help="Grid points per side of each pair of parameters' profile (0: none).",
        ),
    ] = 4,
    workers: WorkersOpt = None,
    sets: SetOpt = None,
    engine: EngineOpt = Engine.auto,
    json_out: JsonOpt = False,
    fresh: FreshOpt = False,
    no_report: NoReportOpt = False,
    force: ForceOpt = False,
) -> None:
    """Fit scenario fields so the twin reproduces measured points (a twin of your own line)."""
    problem, overrides = _problem(
        scenario, targets, fit or [], sets, policy, replications, max_evals, profile, pairs
    )
    _check_work(problem, force)
    inputs = inputs_of(scenario, problem.scenario, **{"targets file": targets}, policy=policy)
    with claim_folder(out, "calibrate", inputs), _journal(out, fresh):
        args = (scenario, overrides, no_report, json_out)
        _calibrate(problem, out, workers, engine.value, *args)


def _calibrate(
    problem: Problem,
    out: Path,
    workers: int | None,
    engine: str,
    scenario: str,
    overrides: dict[str, Any],
    no_report: bool,
    json_out: bool,
) -> None:
    """Fit, write the outputs and show the answer (the lock is held by the caller)."""
    w = workers if workers is not None else (os.cpu_count() or 1)
    err = Console(stderr=True, highlight=False)
    bar = Progress(
        TextColumn("[bold]calibrate"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("evaluations  best objective {task.fields[best]}"),
        TimeElapsedColumn(),
        console=err,
    )
    task = bar.add_task("calibrate", total=problem.max_evals, best="-")

    def update(done: int, best: float) -> None:
        bar.update(task, completed=done, total=max(done, problem.max_evals), best=f"{best:.4g}")

    with bar:
        cal = calibrate(problem, out, workers=w, progress=update, engine=engine)
    command = shlex.join(["pnp-twin", *sys.argv[1:]])
    info = write_outputs(cal, out, scenario, overrides, command)
    if not no_report:
        _write_report(out, err)
    if json_out:
        keep = ("history", "profiles", "curves")
        typer.echo(dumps_json({k: v for k, v in info.items() if k not in keep}, indent=2))
        return
    console = Console(highlight=False)
    if not console.is_terminal:
        console.width = max(console.width, 120)
    console.print(_fitted_table(info))
    console.print(_points_table(info))
    if info["lower_found"]:
        low = info["lower_found"]
        err.print(
            f"note: the profiles found a lower objective ({low['objective']:.4g} at "
            f"{low['x']}); rerun with more --max-evals or start there (--set)"
        )
    console.print(
        f"scenario file: {info['scenario_file']}  ({info['evaluations']} evaluations, "
        f"{info['simulated_points']} points simulated, {info['replayed_points']} "
        f"replayed, {info['wall_time']:.0f} s)"
    )
