"""The ``sweep``, ``size`` and ``mix`` commands of ``pnp-twin``: studies into a folder.

Each runs its study (``pnp_twin.studies``) with a progress bar on stderr (runs done, runs per
second, time left), prints a short summary table on stdout, and writes the HTML report
(``reports.build_report``) into the study folder. Re-running the same command resumes.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shlex
import sys
import textwrap
import time
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import pandas as pd
import typer
from rich import box
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from pnp_twin.cli.app import (
    Engine,
    EngineOpt,
    ForceOpt,
    FreshOpt,
    KpiOpt,
    NoReportOpt,
    SetOpt,
    WorkersOpt,
    app,
)
from pnp_twin.cli.claim import claim_folder, inputs_of
from pnp_twin.cli.console import note, stderr_console, stdout_console
from pnp_twin.cli.decision_opts import AcrossOpt, WriteScenarioOpt
from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.costing import check_costs, read_costs
from pnp_twin.studies.deploy import check_scenario_out, scenario_file_text, write_scenario_file
from pnp_twin.studies.design_conditions import parse_across
from pnp_twin.studies.folder import Tables
from pnp_twin.studies.kpi_choice import parse_kpi
from pnp_twin.studies.plan import AUTO
from pnp_twin.studies.rulemix import DEFAULT_BUDGET, check_mix, run_mix
from pnp_twin.studies.sizing import COUNT, MTBF, check_size, run_size
from pnp_twin.twin.budget import check_study
from pnp_twin.twin.errors import UserError, excerpt
from pnp_twin.twin.loader import (
    ScenarioError,
    load_scenario,
    parse_sets,
    with_overrides,
)
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)


class Backend(StrEnum):
    """Where the runs execute."""

    local = "local"
    ray = "ray"


ScenarioArg = Annotated[
    str,
    typer.Argument(
        help="A scenario file with a [sweep] section, or a shipped name (see `pnp-twin list`).",
        show_default=False,
    ),
]
OutOpt = Annotated[
    Path,
    typer.Option(
        "--out", "-o", help="Study folder (created; rerun to resume).", show_default=False
    ),
]
BackendOpt = Annotated[Backend, typer.Option("--backend", help="local process pool or ray.")]
AddressOpt = Annotated[
    str | None,
    typer.Option("--address", help="Ray cluster address (default RAY_ADDRESS, else a local Ray)."),
]
RepsOpt = Annotated[
    str | None,
    typer.Option(
        "--replications",
        "-r",
        metavar="N|auto",
        help="Replications per point and policy, or auto: add rounds until --half-width is "
        "met (default sweep's).",
    ),
]
HalfWidthOpt = Annotated[
    float | None,
    typer.Option(
        "--half-width",
        metavar="POINTS",
        help="With -r auto: target CI half-width of the gripping rate, percentage points.",
    ),
]
MaxRepsOpt = Annotated[
    int | None,
    typer.Option("--max-replications", metavar="N", help="With -r auto: at most N (30)."),
]
PolicyOpt = Annotated[
    list[str] | None,
    typer.Option("--policy", "-p", help="Policy to compare (repeatable; default sweep's)."),
]
CostsOpt = Annotated[
    Path | None,
    typer.Option(
        "--costs",
        metavar="FILE",
        help="Cost file (TOML, as design's): the what-if panel shows each point's total cost.",
    ),
]


class RateColumn(ProgressColumn):
    """Runs per second of the runs executed in this invocation (resumed ones excluded)."""

    def render(self, task: Task) -> Text:
        rate = task.fields.get("rate")
        return Text(f"{rate:.1f} runs/s" if rate else "- runs/s", style="progress.data.speed")


@contextmanager
def progress_bar(label: str) -> Iterator[Any]:
    """A rich progress bar on stderr; yields the study's progress callback.

    The bar appears with the first progress report, so a study refused before it opens
    its folder (a bad plan, a held or damaged folder) prints nothing but its error line.
    """
    console = stderr_console()
    bar = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("runs"),
        RateColumn(),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
        console=console,
        transient=False,
    )
    # runs executed now arrive one by one; resumed ones arrive as one jump and do not count
    state = {"last": 0, "ran": 0, "t0": time.perf_counter()}
    task = bar.add_task(label, total=None, rate=0.0)

    def update(done: int, total: int) -> None:
        if not bar.live.is_started:  # drawn once the study has opened its folder
            bar.start()
        if done - state["last"] == 1:
            state["ran"] += 1
        state["last"] = done
        elapsed = time.perf_counter() - state["t0"]
        rate = state["ran"] / elapsed if state["ran"] and elapsed > 0 else 0.0
        bar.update(task, completed=done, total=max(total, done), rate=rate)

    try:
        yield update
    except BaseException:
        if not state["last"]:  # nothing done: the error line alone says what happened
            bar.live.transient = True
            console.quiet = True  # not even the line the bar would end with
        raise
    finally:
        if bar.live.is_started:
            bar.stop()
        console.quiet = False


def _options(
    workers: int | None,
    backend: Backend,
    address: str | None,
    fresh: bool,
    progress: Any,
    confidence: float = 0.95,
    engine: Engine = Engine.auto,
) -> Options:
    w = workers if workers is not None else (os.cpu_count() or 1)
    command = shlex.join(["pnp-twin", *sys.argv[1:]])
    opts = Options(backend.value, w, address, fresh, progress, command, confidence)
    opts.engine = engine.value
    return opts


def _costs(path: Path | None, scenarios: Sequence[Scenario]) -> dict[str, Any] | None:
    """``--costs``: the prices, checked against every arm and belt speed the study runs
    (sweep, size and mix share it)."""
    if path is None:
        return None
    prices = read_costs(path)
    check_costs(prices, scenarios)
    return prices


def _load(scenario: str, sets: list[str] | None) -> Scenario:
    return load_scenario(scenario, parse_sets(sets or []))


def _check_work(
    sc: Scenario,
    reps: int | str | None,
    policies: int,
    force: bool,
    extra_points: int = 1,
    grid: dict[str, Any] | None = None,
) -> None:
    """Before planning: at least 2 replications (every study reports CIs), and the study
    within the work limits of :mod:`twin.budget` unless --force."""
    sweep = sc.sweep
    n = reps if reps is not None else (sweep.replications if sweep else 5)
    if n == AUTO:
        n = sweep.max_replications if sweep and sweep.max_replications else 30
    elif isinstance(n, int) and n < 2:
        raise UserError(
            f"--replications: {n} is not allowed; a confidence interval needs at least 2 "
            "replications; give -r 2 or more"
        )
    if grid is None:
        grid = dict(sweep.grid) if sweep else {}
    check_study(sc, grid, policies, int(n), force, extra_points)


def _policy_count(sc: Scenario, policy: list[str] | None) -> int:
    return len(policy or (sc.sweep.policies if sc.sweep else ()) or [sc.policy])


def _replications(value: str | None) -> int | str | None:
    """``--replications``: a whole number >= 1, or auto."""
    if value is None:
        return None
    text = value.strip().lower()
    if text == AUTO:
        return AUTO
    try:
        return int(text)
    except ValueError:
        raise UserError(
            f"--replications: '{value}' is not allowed; give a whole number >= 1 or auto"
        ) from None


def _with_precision(
    sc: Scenario, replications: str | None, half_width: float | None, most: int | None
) -> tuple[Scenario, int | None]:
    """The scenario with -r auto's settings in its sweep section (where every study reads
    them), and the replications to pass on."""
    reps = _replications(replications)
    if not isinstance(reps, str) and half_width is None and most is None:
        return sc, reps
    sets: dict[str, Any] = {"sweep.replications": reps} if reps is not None else {}
    if half_width is not None:
        sets["sweep.half_width"] = half_width
    if most is not None:
        sets["sweep.max_replications"] = most
    try:
        sc = with_overrides(sc, sets)
    except ScenarioError as e:
        raise UserError(str(e)) from None
    auto = sc.sweep is not None and sc.sweep.replications == AUTO
    if not auto:
        which = "--half-width" if half_width is not None else "--max-replications"
        raise UserError(f"{which}: only with --replications auto")
    return sc, None


def _precision_line(out: Path) -> str | None:
    try:
        p = json.loads((out / "meta.json").read_text(encoding="utf-8")).get("precision")
    except (OSError, ValueError):
        return None
    if not p:
        return None
    state = "met at every point" if p["reached"] else f"not met at {p['points_short']} point(s)"
    if p.get("points_undefined"):
        state += f", undefined (no parts) at {p['points_undefined']}"
    return (
        f"replications: {p['replications']} (rounds {', '.join(map(str, p['rounds']))}); "
        f"target half-width {p['target_half_width']:g} points {state}; widest "
        f"{p['half_width_max']:.2f} points"
    )


def _claim(
    kind: str, out: Path, scenario: str, sc: Scenario, policy: list[str] | None, costs: Path | None
) -> AbstractContextManager[str]:
    """The study folder claimed for a ``kind`` study (its journal locks it): checked before
    anything is written (new, empty or a ``kind`` study to resume; holding no input and
    inside none), its kind recorded, removed again if the study is refused before a run."""
    inputs = inputs_of(scenario, sc, costs=costs, policy=policy)
    return claim_folder(out, kind, inputs, lock=False)


def _report(out: Path, skip: bool) -> None:
    if skip:
        return
    err = stderr_console()
    try:
        from pnp_twin.reports import build_report
    except ImportError as e:
        err.print(f"note: report not written ({e})")
        return
    path = build_report(out)
    err.print(f"report: {path}")


def _g(mean: float, low: float, high: float) -> str:
    if math.isnan(low):
        return f"{mean:.2f}"
    return f"{mean:.2f} [{low:.2f}, {high:.2f}]"


def _sweep_table(tables: Tables, grid: list[str], limit: int = 30) -> Table:
    t = Table(title="Best policy per grid point (gripping rate %, 95 % CI)", box=box.SIMPLE)
    for c in grid:
        t.add_column(c, justify="right")
    t.add_column("best")
    t.add_column("G %", justify="right")
    t.add_column("runner-up (diff, pp)")
    s, p = tables.summary, tables.paired
    for _, b in tables.best.head(limit).iterrows():
        row = s[(s["point"] == b["point"]) & (s["policy"] == b["policy"])].iloc[0]
        others = p[(p["point"] == b["point"]) & (p["policy"] != b["policy"])]
        second = ""
        if len(others):
            o = others.loc[others["diff_mean"].idxmax()]
            second = f"{o['policy']} ({o['diff_mean']:+.2f})"
        t.add_row(
            *(str(b[c]) for c in grid),
            str(b["policy"]),
            _g(
                row["gripping_rate_mean"], row["gripping_rate_ci_low"], row["gripping_rate_ci_high"]
            ),
            second,
        )
    if len(tables.best) > limit:
        t.caption = f"first {limit} of {len(tables.best)} points; all in best.csv"
    return t


@app.command("sweep")
def sweep(
    scenario: ScenarioArg,
    out: OutOpt,
    workers: WorkersOpt = None,
    backend: BackendOpt = Backend.local,
    address: AddressOpt = None,
    replications: RepsOpt = None,
    half_width: HalfWidthOpt = None,
    max_replications: MaxRepsOpt = None,
    sets: SetOpt = None,
    policy: PolicyOpt = None,
    fresh: FreshOpt = False,
    no_report: NoReportOpt = False,
    force: ForceOpt = False,
    engine: EngineOpt = Engine.auto,
    costs: CostsOpt = None,
) -> None:
    """Run a study: the sweep grid x policies x replications (common random numbers)."""
    sc, reps = _with_precision(_load(scenario, sets), replications, half_width, max_replications)
    _check_work(sc, reps, _policy_count(sc, policy), force)
    plan = build_plan(sc, policies=policy, replications=reps)
    prices = _costs(costs, plan.scenarios)
    with _claim("sweep", out, scenario, sc, policy, costs), progress_bar("sweep") as update:
        opts = _options(workers, backend, address, fresh, update, engine=engine)
        opts.costs, opts.costs_file = prices, str(costs or "")
        tables = run_sweep(plan, out, opts)
    stdout_console().print(_sweep_table(tables, list(plan.grid)))
    line = _precision_line(out)
    if line:
        note(line)
    _report(out, no_report)


def with_conditions(sc: Scenario, across: list[str]) -> Scenario:
    """``size --across PATH=V1,V2``: each a condition of sweep.grid, which size already
    requires every count to meet the target at (an intersection-union test: each condition
    at the full level, so the claim 'meets at every condition' keeps the confidence)."""
    if not across:
        return sc
    grid = {**(sc.sweep.grid if sc.sweep else {}), **parse_across(across, sc)}
    if any(p in (sc.sweep.grid if sc.sweep else {}) for p in parse_across(across, sc)):
        raise UserError("--across: a field already in sweep.grid; give it in one place")
    shifts = "feeder.trace" in grid and sc.feeder.arrival != "trace"  # each shift replayed
    return with_overrides(
        sc, {"sweep.grid": grid, **({"feeder.arrival": "trace"} if shifts else {})}
    )


def _write_choice(sizing: dict[str, Any], path: Path, sc: Scenario) -> None:
    spec = sizing.get("showcase_spec")
    if spec is None:
        note(f"--write-scenario: nothing written to {path}: no count meets the target")
        return
    text = scenario_file_text(
        spec.scenario.model_dump(mode="json"),
        spec.policy,
        [spec.seed],
        shlex.join(["pnp-twin", *sys.argv[1:]]),
        textwrap.wrap(sizing["text"], 96),
        sc.source_dir,
    )
    note(f"scenario: {write_scenario_file(path, text)}")


@app.command("size")
def size(
    scenario: ScenarioArg,
    out: OutOpt,
    target: Annotated[
        float | None, typer.Option("--target", help="Target gripping rate in % (or sweep.target).")
    ] = None,
    confidence: Annotated[float, typer.Option("--confidence", help="Confidence level.")] = 0.95,
    workers: WorkersOpt = None,
    backend: BackendOpt = Backend.local,
    address: AddressOpt = None,
    replications: RepsOpt = None,
    half_width: HalfWidthOpt = None,
    max_replications: MaxRepsOpt = None,
    sets: SetOpt = None,
    policy: PolicyOpt = None,
    fresh: FreshOpt = False,
    no_report: NoReportOpt = False,
    layout: Annotated[
        str,
        typer.Option(
            "--layout",
            help="extend: lengthen the belt for more robots; share: keep the belt, narrower "
            "workspaces.",
        ),
    ] = "extend",
    force: ForceOpt = False,
    engine: EngineOpt = Engine.auto,
    costs: CostsOpt = None,
    kpi: KpiOpt = "gripping_rate",
    across: AcrossOpt = None,
    write_scenario: WriteScenarioOpt = None,
) -> None:
    """The smallest robot count reaching a target gripping rate with a confidence."""
    sc, reps = _with_precision(_load(scenario, sets), replications, half_width, max_replications)
    sc = with_conditions(sc, across or [])
    figure = parse_kpi(kpi, sc)
    grid = sc.sweep.grid if sc.sweep else {}
    counts = 1 if COUNT in grid else max(8, 2 * sc.robots.count)  # what run_size adds
    _check_work(sc, reps, _policy_count(sc, policy), force, counts * (1 if MTBF in grid else 2))
    target = check_size(sc, target, confidence, policy, reps, layout)
    plan = build_plan(sc, policies=policy, replications=reps) if costs else None
    prices = _costs(costs, plan.scenarios) if plan is not None else None
    if write_scenario is not None:
        inputs = inputs_of(scenario, sc, costs=costs, policy=policy)
        check_scenario_out(write_scenario, inputs, "--write-scenario")
    opts = _options(workers, backend, address, fresh, None, confidence, engine)
    opts.costs, opts.costs_file = prices, str(costs or "")
    opts.kpi = figure
    with _claim("size", out, scenario, sc, policy, costs), progress_bar("size") as update:
        opts.progress = update
        tables, sizing = run_size(sc, out, target, opts, policy, reps, layout)
    if write_scenario is not None:
        _write_choice(sizing, write_scenario, sc)
    rows = pd.DataFrame(sizing["rows"])
    rows = rows[rows[MTBF] == 0] if MTBF in rows else rows
    t = Table(
        title=f"{figure.noun.capitalize() if figure.kind is None else figure.noun} % by robot "
        f"count ({100 * confidence:g} % CI of the rule picked at each count)",
        box=box.SIMPLE,
    )
    others = [c for c in rows.columns if "." in c and c not in (COUNT, MTBF)]
    for c in [COUNT, *others]:
        t.add_column(c, justify="right")
    t.add_column("policy")
    t.add_column(f"{figure.short} %", justify="right")
    t.add_column(f">= {sizing['target']:g} %")
    for _, r in rows.iterrows():
        t.add_row(
            *(str(r[c]) for c in [COUNT, *others]),
            str(r["policy"]),
            _g(r["gripping_rate_mean"], r["ci_low"], r["ci_high"]),
            "yes" if r["reached"] else "no",
        )
    console = stdout_console()
    console.print(t)
    console.print(sizing["text"])
    line = _precision_line(out)
    if line:
        note(line)
    _report(out, no_report)


def _rule_list(rules: str | None) -> list[str] | None:
    """``--rules``: None when left out; else the names between commas, none of them empty."""
    if rules is None:
        return None
    names = [r.strip() for r in rules.split(",")]
    if not any(names):
        raise UserError(
            f"--rules: {excerpt(rules)} names no rule; give rules separated by commas, e.g. "
            "--rules SPT,SD,FIFO, or leave --rules out for sweep.policies"
        )
    if not all(names):
        raise UserError(
            f"--rules: {excerpt(rules)} has an empty name between commas; give e.g. SPT,SD,FIFO"
        )
    return names


@app.command("mix")
def mix(
    scenario: ScenarioArg,
    out: OutOpt,
    rules: Annotated[
        str | None,
        typer.Option("--rules", help="Rules to mix, comma-separated (default sweep.policies)."),
    ] = None,
    budget: Annotated[
        int, typer.Option("--budget", help="Most mixes a GRASP search evaluates.")
    ] = DEFAULT_BUDGET,
    workers: WorkersOpt = None,
    backend: BackendOpt = Backend.local,
    address: AddressOpt = None,
    replications: RepsOpt = None,
    sets: SetOpt = None,
    fresh: FreshOpt = False,
    no_report: NoReportOpt = False,
    force: ForceOpt = False,
    engine: EngineOpt = Engine.auto,
    costs: CostsOpt = None,
) -> None:
    """Search the best per-robot mix of dispatching rules (exhaustive or GRASP)."""
    sc = _load(scenario, sets)
    reps = _replications(replications)
    if reps == AUTO or (reps is None and sc.sweep is not None and sc.sweep.replications == AUTO):
        raise UserError(
            "--replications: auto is not for mix (every mix is scored on the same fixed "
            "replications); give a number, e.g. -r 5"
        )
    if budget < 1:
        raise UserError(f"--budget: {budget} is not allowed; give 1 or more mixes")
    _check_work(sc, reps, budget, force, grid={})  # a mix search sweeps no grid
    names = _rule_list(rules)
    check_mix(sc, names, reps if isinstance(reps, int) else None, budget)
    prices = _costs(costs, [sc])  # every mix runs the same line: one price
    opts = _options(workers, backend, address, fresh, None, engine=engine)
    opts.costs, opts.costs_file = prices, str(costs or "")
    with _claim("mix", out, scenario, sc, None, costs), progress_bar("mix") as update:
        opts.progress = update
        _, result = run_mix(sc, out, opts, names, reps if isinstance(reps, int) else None, budget)
    t = Table(
        title=f"Best rule mixes ({result['method']}, {result['evaluated']} evaluated; "
        "gripping rate %, 95 % CI)",
        box=box.SIMPLE,
    )
    t.add_column("#", justify="right")
    t.add_column("mix")
    t.add_column("G %", justify="right")
    if prices is not None:
        t.add_column("total cost", justify="right")
    for i, r in enumerate(result["ranked"][:10], start=1):
        cost = [f"{r['total_cost']:,.0f}"] if prices is not None else []
        t.add_row(str(i), r["mix"], _g(r["gripping_rate_mean"], r["ci_low"], r["ci_high"]), *cost)
    stdout_console().print(t)
    from pnp_twin.reports.answers import (
        mix_headline,  # the report's answer, best vs runner-up paired
    )

    stdout_console().print(mix_headline(result))
    _report(out, no_report)
