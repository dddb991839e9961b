"""The ``run``, ``validate``, ``schema`` and ``list`` commands of ``pnp-twin``.

``run`` simulates one scenario with one policy and shows its KPIs (a table, or one JSON
object with ``--json``); ``validate`` checks a scenario file and prints it resolved;
``schema`` prints the scenario JSON Schema for editors; ``list`` shows the shipped
scenarios. Tables and JSON go to stdout; progress and notes go to stderr.
"""

from __future__ import annotations

import contextlib
import json
import math
from enum import StrEnum
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.table import Table

from pnp_twin.cli.app import Engine, ScenarioArg, SetOpt, app
from pnp_twin.cli.claim import inputs_of
from pnp_twin.cli.console import note, stderr_console, stdout_console
from pnp_twin.policies import make_policy
from pnp_twin.twin.budget import check_run
from pnp_twin.twin.loader import (
    ScenarioError,
    load_scenario,
    parse_sets,
    shipped_scenarios,
)
from pnp_twin.twin.output import (
    OutputError,
    check_not_inputs,
    check_table_path,
    check_writable,
    dumps_json,
    dumps_toml,
    same_file,
    write_table,
    write_text,
)
from pnp_twin.twin.run import RunResult, simulate
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import read_trace, trace_file, trace_files


class TextFormat(StrEnum):
    """Formats ``validate`` prints a resolved scenario in."""

    toml = "toml"
    yaml = "yaml"


def _load(scenario: str, sets: list[str] | None) -> Scenario:
    return load_scenario(scenario, parse_sets(sets or []))


@app.command("run")
def run(
    scenario: ScenarioArg,
    policy: Annotated[
        str | None,
        typer.Option(
            "--policy",
            "-p",
            metavar="NAME|MIX",
            help="Rule (FIFO LIFO SIRO SD LD SPT), a per-robot mix such as SPT,SPT,SPT,FIFO, "
            "or prefix:ARG; default the scenario's policy.",
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option("--seed", min=0, metavar="N", help="Master seed; default the scenario's."),
    ] = None,
    sets: SetOpt = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object of KPIs instead of tables.")
    ] = False,
    events: Annotated[
        Path | None,
        typer.Option(
            "--events",
            metavar="FILE",
            help="Write the per-part records to FILE (.csv or .parquet).",
        ),
    ] = None,
    spans: Annotated[
        Path | None,
        typer.Option(
            "--spans",
            metavar="FILE",
            help="Write the robot state spans to FILE (.csv or .parquet).",
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Run even above the work limit (twin.budget).")
    ] = False,
    engine: Annotated[
        Engine,
        typer.Option(
            "--engine",
            help="simpy (the reference), fast (compiled, same events; rules and mixes) or "
            "auto (fast where it can).",
        ),
    ] = Engine.simpy,
    report: Annotated[
        Path | None,
        typer.Option(
            "--report",
            metavar="FILE",
            help="Write the run's HTML report (KPIs, replay, robots, timeline, warm-up) to FILE.",
        ),
    ] = None,
    replay_window: Annotated[
        float,
        typer.Option(
            "--replay-window",
            min=1.0,
            max=3600.0,
            metavar="SECONDS",
            help="How much of the run the report's replay and --gif show, from the end of "
            "the warm-up (about 0.1 MB per simulated minute on paper_baseline).",
        ),
    ] = 60.0,
    gif: Annotated[
        Path | None,
        typer.Option(
            "--gif",
            metavar="FILE",
            help="Write the replay window as an animated GIF to FILE (5x speed; needs the "
            "gif extra: imageio, Pillow).",
        ),
    ] = None,
) -> None:
    """Simulate SCENARIO with a policy and show its KPIs."""
    if report is not None and report.suffix.lower() not in (".html", ".htm"):
        raise OutputError(f"--report: '{report}' must end in .html")
    if report is not None:
        check_writable(report, "--report")
    if gif is not None:
        if gif.suffix.lower() != ".gif":
            raise OutputError(f"--gif: '{gif}' must end in .gif")
        check_writable(gif, "--gif")
    if events is not None:
        check_table_path(events, "--events")
    if spans is not None:
        check_table_path(spans, "--spans")
    if events is not None and spans is not None and same_file(events, spans):
        raise OutputError(
            f"--spans: '{spans}' is the file --events writes; give the two different files"
        )
    if report is not None:
        for option, other in (("--events", events), ("--spans", spans)):
            if other is not None and same_file(report, other):
                raise OutputError(f"--report: '{report}' is the file {option} writes")
    scn = _load(scenario, sets)
    inputs = inputs_of(scenario, scn, policy=policy)
    outputs = (("--events", events), ("--spans", spans), ("--report", report), ("--gif", gif))
    for option, output in outputs:
        if output is not None:
            check_not_inputs(output, inputs, option)
    check_run(scn, force)
    spec = policy if policy is not None else scn.policy
    pol = make_policy(spec, scn.robots.count)
    traces = trace_files(scn)
    if len(traces) > 1:  # one run, one trace: the first (a study replays trace k in rep k)
        note(
            f"feeder.trace: {len(traces)} traces; this run replays the first, "
            f"'{traces[0].name}' (a study replays trace k in replication k)"
        )
    err = stderr_console()
    busy = err.status(f"simulating {scn.name}...") if err.is_terminal else contextlib.nullcontext()
    with busy:
        result = simulate(scn, pol, seed=seed, engine=engine.value)
    if events is not None:
        write_table(result.parts, events, "--events")
        note(f"wrote {len(result.parts)} part records to {events}")
    if spans is not None:
        write_table(result.spans, spans, "--spans")
        note(f"wrote {len(result.spans)} robot state spans to {spans}")
    if report is not None:
        from pnp_twin.reports.record_figures import Animation
        from pnp_twin.reports.run_report import build_run_report  # the front end imports reports

        scenario_dict = scn.model_dump(mode="json")
        window = Animation(seconds=replay_window)
        build_run_report(
            result.kpis, result.parts, result.spans, scenario_dict, report, animation=window
        )
        note(f"report: {report}")
    if gif is not None:
        from pnp_twin.reports.replay_data import replay_data
        from pnp_twin.reports.replay_gif import write_gif

        label = f"{result.kpis.get('policy')}, seed {result.kpis.get('seed')}"
        data = replay_data(
            result.parts,
            result.spans,
            scn.model_dump(mode="json"),
            result.kpis.get("seed"),
            None,
            replay_window,
            label,
        )
        write_gif(data, gif)
        note(f"GIF: {gif} ({gif.stat().st_size / 1e6:.1f} MB)")
    stats = getattr(pol, "stats", None)  # a policy that reports its own cost (lookahead)
    extra = {"policy_stats": stats()} if callable(stats) else {}
    if as_json:
        typer.echo(
            dumps_json({**result.kpis, "engine": result.meta.get("engine", "simpy"), **extra})
        )
        return
    out = stdout_console()
    out.print(kpi_table(result))
    out.print(robot_table(result.kpis))
    if "kinds" in result.kpis:
        out.print(kind_table(result.kpis))
        untargeted = [n for n, f in result.kpis["kinds"].items() if not f["targeted"]]
        if untargeted:
            note(
                f"no robot picks {', '.join(untargeted)}: "
                f"{result.kpis['parts_passed_by_design']} parts passed on by design, "
                "left out of G"
            )
    note(
        f"fed {scn.duration:g} s, drained to t = {result.sim_time:,.0f} s, "
        f"in {result.wall_time:.2f} s wall time ({result.meta.get('engine', 'simpy')} engine)"
    )
    if extra:
        ps = extra["policy_stats"]
        note(
            f"{ps.get('policy', 'policy')}: {ps.get('decisions', 0)} decisions "
            f"({ps.get('planned', 0)} planned), {ps.get('cpu_ms_per_decision', math.nan):.2f} ms "
            "CPU per decision"
        )


def _pct(x: float) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{100.0 * x:.1f} %"


def _share(x: float) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{100.0 * x:.1f}"


def _num(x: float, fmt: str = ".3f", unit: str = "") -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:{fmt}}{unit}"


def kpi_table(result: RunResult) -> Table:
    """The run's line-level KPIs as a two-column table."""
    k = result.kpis
    w0, w1 = k["window"]
    capacity = sum(r["capacity"] for r in k["robots"])
    bound = "part flow" if k["part_flow"] <= capacity else "measured cycle rate"
    t = Table(
        title=f"{k['scenario']}: policy {k['policy']}, seed {k['seed']}, {k['termination']}",
        caption=f"parts fed in [{w0:g}, {w1:g}) s; efficiency = throughput / min(part flow, "
        "robots' measured cycle rate = picks per busy second)",
        box=box.SIMPLE_HEAVY,
        show_header=False,
    )
    t.add_column("KPI", style="bold")
    t.add_column("value", justify="right")
    g = k["gripping_rate"]
    t.add_row("Gripping rate G", "n/a" if not math.isfinite(g) else f"{g:.2f} %")
    if "value_rate" in k:
        t.add_row("Value rate (of value presented)", _num(k["value_rate"], ".2f", " %"))
    t.add_row(
        "Parts presented / picked / lost",
        f"{k['parts_presented']} / {k['parts_picked']} / {k['parts_missed']}",
    )
    t.add_row("Throughput", _num(k["throughput"], ".3f", " parts/s"))
    t.add_row("Part flow", _num(k["part_flow"], ".3f", " parts/s"))
    t.add_row("Measured cycle rate (sum)", _num(capacity, ".3f", " parts/s"))
    t.add_row(f"Efficiency (of {bound})", _pct(k["efficiency"]))
    t.add_row("Utilisation (mean)", _pct(k["utilisation"]))
    t.add_row(
        "Cycle time mean / p50 / p95 / max",
        " / ".join(_num(k[f"cycle_time_{s}"], ".3f") for s in ("mean", "p50", "p95", "max")) + " s",
    )
    decisions = ", ".join(f"{rule} {n}" for rule, n in k["decisions"].items()) or "none"
    t.add_row("Decisions per rule", decisions)
    if "fill_rate" in k:  # a line with an outfeed
        t.add_row(
            "Outfeed: containers full (fill rate)",
            f"{k['containers_full']} of {k['containers']} ({_num(k['fill_rate'], '.1f', ' %')})",
        )
        t.add_row("Outfeed: slots filled", _num(k["slots_filled_per_s"], ".3f", " slots/s"))
        at_end = f", {k['parts_held_at_end']} still held at the end" * bool(k["parts_held_at_end"])
        t.add_row(
            "Parts held for a slot / hold time",
            f"{k['parts_held']} / {_num(k['hold_time'], '.1f', ' s')}{at_end}",
        )
        t.add_row(
            "Hold per robot (blocked time)",
            ", ".join(f"{r['robot']}: {_share(r['hold'])}" for r in k["robots"]) + " %",
        )
    return t


def robot_table(kpis: dict[str, Any]) -> Table:
    """One row per robot: picks, throughput and where its time went."""
    t = Table(
        title="Robots (upstream first; workspace x range in m, time shares in %)",
        box=box.SIMPLE_HEAVY,
        pad_edge=False,
        collapse_padding=True,
        caption="passed on = left the workspace unpicked, picked downstream; lost = left it "
        "unpicked, reached the return conveyor",
    )
    for col in ("robot", "x range", "picks", "parts/s", "util", "NooP", "wait", "blocked"):
        t.add_column(col, justify="right")
    for col in ("down", "passed on", "lost"):
        t.add_column(col, justify="right")
    for r in kpis["robots"]:
        a, b = r["workspace"]
        t.add_row(
            str(r["robot"]),
            f"{a:g}-{b:g}",
            str(r["picks"]),
            _num(r["throughput"], ".3f"),
            _share(r["utilisation"]),
            _share(r["noop"]),
            _share(r["wait"]),
            _share(r["blocked"]),
            _share(r["down"]),
            str(r["passed_on"]),
            str(r["lost"]),
        )
    return t


def kind_table(kpis: dict[str, Any]) -> Table:
    """One row per kind of part: presented, picked, lost, gripping rate, value."""
    t = Table(
        title="Kinds of part (value per part; G per kind in %)",
        box=box.SIMPLE_HEAVY,
        pad_edge=False,
        collapse_padding=True,
        caption="passed on by design = a kind no robot picks: left out of G",
    )
    for col in ("kind", "value", "presented", "picked", "lost", "by design", "G", "value %"):
        t.add_column(col, justify="left" if col == "kind" else "right")
    for name, f in kpis["kinds"].items():
        worth = f["value_presented"]
        t.add_row(
            name,
            f"{f['value']:g}",
            str(f["parts_presented"]),
            str(f["parts_picked"]),
            str(f["parts_lost"]),
            str(f["parts_passed_by_design"]),
            _num(f["gripping_rate"], ".1f"),
            _num(100.0 * f["value_picked"] / worth if worth > 0 else math.nan, ".1f"),
        )
    return t


def resolved_mapping(scenario: Scenario) -> dict[str, Any]:
    """The scenario with every default filled in, ready to be written as a scenario file.

    The loader's ``source_dir`` is left out; a relative trace path is made absolute instead,
    so the printed file works from any folder.
    """
    data = scenario.model_dump(mode="json", exclude={"source_dir"})
    trace = scenario.feeder.trace
    if trace and scenario.source_dir:  # one file, a folder, or a list of them
        names = [trace] if isinstance(trace, str) else list(trace)
        absolute = [str(Path(scenario.source_dir) / t) for t in names]  # absolute ones stay
        data["feeder"]["trace"] = absolute[0] if isinstance(trace, str) else absolute
    data = _drop_none(data)
    # run settings first, then the sections, as in the shipped files
    return {k: v for k, v in data.items() if not isinstance(v, dict)} | {
        k: v for k, v in data.items() if isinstance(v, dict)
    }


def _drop_none(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _drop_none(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, list):
        return [_drop_none(v) for v in obj]
    return obj


@app.command("validate")
def validate(
    scenario: ScenarioArg,
    sets: SetOpt = None,
    fmt: Annotated[
        TextFormat, typer.Option("--format", "-f", help="How to print the resolved scenario.")
    ] = TextFormat.toml,
) -> None:
    """Check SCENARIO (fields, policy, trace file) and print it with every default resolved."""
    scn = _load(scenario, sets)
    make_policy(scn.policy, scn.robots.count)
    notes = [f"{scn.robots.count} robots", f"policy {scn.policy}"]
    trace = trace_file(scn)
    if trace is not None:
        times, _, _ = read_trace(trace, scn.belt.width)
        span = float(times[-1]) if len(times) else 0.0
        notes.append(f"trace of {len(times)} parts over {span:g} s")
        if span < 0.95 * scn.duration:
            notes.append(
                f"the feed stops after the trace ends, before duration = {scn.duration:g} s"
            )
    data = resolved_mapping(scn)
    if fmt is TextFormat.yaml:
        import yaml

        text = yaml.safe_dump(data, sort_keys=False, default_flow_style=False, width=100)
    else:
        text = dumps_toml(data)
    typer.echo(f"# {scn.name}: resolved by pnp-twin validate\n{text}", nl=False)
    note(f"ok: {scenario} is a valid scenario ({'; '.join(notes)})")


def schema_text() -> str:
    """The JSON Schema of a scenario file, as written to ``scenarios/scenario.schema.json``."""
    schema = {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        **Scenario.model_json_schema(),
    }
    return json.dumps(schema, indent=2) + "\n"


@app.command("schema")
def schema(
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", metavar="FILE", help="Write the schema to FILE instead."),
    ] = None,
) -> None:
    """Print the JSON Schema of scenario files (for editors and validators)."""
    if out is not None:
        check_writable(out, "--out")
    text = schema_text()
    if out is None:
        typer.echo(text, nl=False)
        return
    write_text(text, out)
    note(f"wrote the scenario schema to {out}")


@app.command("list")
def list_scenarios() -> None:
    """List the shipped scenarios, usable by name in place of a path."""
    t = Table(title="Shipped scenarios", box=box.SIMPLE_HEAVY)
    for col in ("name", "robots", "feed", "policy", "description"):
        t.add_column(col)
    for name in shipped_scenarios():
        try:
            s = load_scenario(name)
        except ScenarioError as e:
            t.add_row(name, "", "", "", f"[red]invalid: {e}[/red]")
            continue
        feed = "trace" if s.feeder.arrival == "trace" else f"{s.feeder.rate:g}/s {s.feeder.arrival}"
        t.add_row(name, str(s.robots.count), feed, s.policy, s.description)
    stdout_console().print(t)
    models = resources.files("pnp_twin.models")
    names = sorted(m.name for m in models.iterdir() if (m / "meta.json").is_file())
    if names:
        stdout_console().print(
            "Shipped models (--policy hdqn:NAME, needs the learn extra): " + ", ".join(names)
        )
