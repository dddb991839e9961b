"""The ``headroom`` command of ``pnp-twin``: how much smarter coordination could gain.

Runs :func:`pnp_twin.studies.headroom.run_headroom` (best rule, best static mix, the given
policies, the lookahead controller and its clairvoyant bound, paired by seed) and writes
``headroom.json``, ``runs.csv``, ``summary.csv`` and ``report.html`` into ``--out`` (under the
folder's study lock, each file written atomically); prints the answer and a table, or the
JSON with ``--json``. Every run is stored in ``--out``'s ``evals/runs.sqlite`` as it finishes,
so the same command after a kill resumes: finished runs are read back, not simulated.
"""

from __future__ import annotations

import math
from contextlib import nullcontext
from pathlib import Path
from typing import Annotated

import typer
from rich import box
from rich.table import Table

from pnp_twin.cli.app import (
    Engine,
    EngineOpt,
    ForceOpt,
    JsonOpt,
    KpiOpt,
    ProcessesOpt,
    RunDurationOpt,
    ScenarioArg,
    SetOpt,
    app,
)
from pnp_twin.cli.claim import claim_folder, inputs_of
from pnp_twin.cli.console import note, stdout_console
from pnp_twin.cli.decision_opts import RayAddressOpt, RayBackendOpt, executor
from pnp_twin.cli.study_folder import with_duration
from pnp_twin.parallel import ray_session
from pnp_twin.policies.rules import RULES
from pnp_twin.studies.calibrate_eval import EVALS
from pnp_twin.studies.headroom import BOUND_NOTE, Headroom, HeadroomSettings, check_policies
from pnp_twin.studies.kpi_choice import parse_kpi
from pnp_twin.twin.budget import check_study
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.output import dumps_json


@app.command("headroom")
def headroom(
    scenario: ScenarioArg,
    out: Annotated[
        Path,
        typer.Option(
            "--out", metavar="DIR", help="The study folder (created).", show_default=False
        ),
    ],
    seeds: Annotated[
        int, typer.Option("--seeds", min=2, max=10_000, help="Held-out seeds FIRST..FIRST+N-1.")
    ] = 20,
    first_seed: Annotated[int, typer.Option("--first-seed", min=0, help="First seed.")] = 0,
    policy: Annotated[
        list[str] | None,
        typer.Option(
            "--policy",
            "-p",
            metavar="P",
            help="Another policy to place, e.g. hdqn:models/paper_baseline__async_rollout "
            "(repeatable).",
        ),
    ] = None,
    lookahead: Annotated[
        str,
        typer.Option(
            "--lookahead",
            metavar="SPEC",
            help="The lookahead controller, e.g. lookahead:K=32,H=1.5,base=SD; the bound is "
            "the same with oracle=1.",
        ),
    ] = "lookahead",
    mix: Annotated[
        str | None,
        typer.Option("--mix", help="The best static mix (default: searched on tuning seeds)."),
    ] = None,
    duration: RunDurationOpt = None,
    sets: SetOpt = None,
    workers: ProcessesOpt = 1,
    engine: EngineOpt = Engine.fast,
    as_json: JsonOpt = False,
    kpi: KpiOpt = "gripping_rate",
    force: ForceOpt = False,
    backend: RayBackendOpt = "local",
    address: RayAddressOpt = None,
) -> None:
    """How much could smarter coordination gain? Best rule, best mix, given policies, the
    lookahead controller and its clairvoyant bound, paired by seed."""
    sc = load_scenario(scenario, parse_sets(sets or []))
    figure = parse_kpi(kpi, sc)
    sc = with_duration(sc, duration)
    settings = HeadroomSettings(
        seeds=seeds,
        first_seed=first_seed,
        policies=tuple(policy or ()),
        lookahead=lookahead,
        mix=mix,
        engine=engine.value,
        workers=workers,
        kpi=figure,
        backend=backend,
        address=address,
    )
    executor(backend, workers, address)  # a bad backend or address: one line, nothing made
    check_policies(sc, settings)  # a bad name fails before the folder is made
    runs = len(settings.policies) + len(RULES) + 4  # + VAL, the mix, lookahead, bound
    check_study(sc, {}, runs, seeds, force)
    from pnp_twin.studies.headroom import run_headroom
    from pnp_twin.studies.runstore import open_store

    with claim_folder(out, "headroom", inputs_of(scenario, sc, policy=policy)):
        with open_store(out / EVALS) as store:  # every run as it finishes: a kill resumes
            with ray_session(workers, address) if backend == "ray" else nullcontext():
                result = run_headroom(sc, settings, _progress, store)
        write_headroom(result, out)
    if as_json:
        typer.echo(dumps_json(result.to_json(), indent=2))
        return
    stdout_console().print(_table(result))
    typer.echo(result.to_json()["answer"])
    note(f"note: {BOUND_NOTE}")
    note(f"wrote {out}/headroom.json, runs.csv, summary.csv, report.html")


def write_headroom(result: Headroom, out: Path) -> None:
    """The study's files, each written atomically."""
    import pandas as pd

    from pnp_twin.reports.headroom_report import headroom_html
    from pnp_twin.twin.output import write_json, write_table, write_text

    data = result.to_json()
    write_table(pd.DataFrame(result.runs()), out / "runs.csv")
    summary = [{"role": e.role, **e.row()} for e in result.entries]
    write_table(pd.DataFrame(summary), out / "summary.csv")
    write_text(headroom_html(data), out / "report.html")
    write_json(data, out / "headroom.json")  # last: a folder with it holds a finished study


def _progress(spec: str, done: int, total: int) -> None:
    if total and done == total:
        note(f"{spec}: {done} runs")


def _fmt(x: float, sign: bool = False) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:+.2f}" if sign else f"{x:.2f}"


def _table(result: Headroom) -> Table:
    s = result.settings
    t = Table(
        title=f"{result.scenario.name}: headroom over the best rule, seeds "
        f"{s.seed_list[0]}..{s.seed_list[-1]} (paired 95 % CI)",
        box=box.SIMPLE,
    )
    figure = f"{s.kpi.short} %"
    for col in ("role", "policy", figure, "95 % CI", "gain", "paired 95 % CI", "ms/decision"):
        t.add_column(col, justify="left" if col in ("role", "policy") else "right")
    shown = [result.best_rule, result.best_mix, *result.policies, result.lookahead, result.bound]
    for e in shown:
        role = "best rule" if e is result.best_rule else e.role.replace("_", " ")
        cpu = e.cpu_ms_per_decision
        t.add_row(
            role,
            e.policy,
            _fmt(e.gripping_rate),
            f"[{_fmt(e.ci_low)}, {_fmt(e.ci_high)}]",
            _fmt(e.gain, True),
            f"[{_fmt(e.gain_ci_low, True)}, {_fmt(e.gain_ci_high, True)}]",
            "" if cpu is None else f"{cpu:.2f}",
        )
    return t
