"""The ``task`` command of ``pnp-twin``: the task suite (:mod:`pnp_twin.learning.tasks`).

``pnp-twin task list`` prints the tasks (line, seeds, description); ``pnp-twin task score
TASK --policy P`` runs the policy and the six rules on the task's evaluation seeds (common
random numbers) and prints the policy's mean G with its 95 % t-interval and its paired
difference to the task's best rule with its paired 95 % interval (``--json``: one object).
"""

from __future__ import annotations

import math
from typing import Annotated

import typer
from rich import box
from rich.table import Table

from pnp_twin.cli.app import Engine, EngineOpt, ProcessesOpt, app
from pnp_twin.cli.console import note, stdout_console
from pnp_twin.twin.output import dumps_json

task_app = typer.Typer(
    name="task",
    help="The task suite: list the tasks, score a policy on one.",
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)
app.add_typer(task_app, name="task")


@task_app.callback(invoke_without_command=True)
def task_root(ctx: typer.Context) -> None:
    """The task suite: list the tasks, score a policy on one."""
    if ctx.invoked_subcommand is None:  # bare `pnp-twin task`: show what it can do
        typer.echo(ctx.get_help())
        raise typer.Exit()


@task_app.command("list")
def task_list(
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the tasks as one JSON object.")
    ] = False,
) -> None:
    """The tasks: line, termination, run length, seeds and a one-line description."""
    from pnp_twin.learning.tasks import SUITE

    if as_json:
        typer.echo(dumps_json({"tasks": [t.to_json() for t in SUITE]}, indent=2))
        return
    t = Table(title="Tasks (metric: G %, parts gripped of those fed after the warm-up)",
              box=box.SIMPLE)  # fmt: skip
    for col in ("task", "line", "eval seeds", "description"):
        t.add_column(col)
    for task in SUITE:
        t.add_row(
            task.name,
            task.line_text(),
            f"{task.eval_seeds.start}-{task.eval_seeds.stop - 1}",
            task.description,
        )
    stdout_console().print(t)
    runs = sorted({(x.duration, x.warmup, x.termination) for x in SUITE})
    train = sorted({(x.train_seeds.start, x.train_seeds.stop - 1) for x in SUITE})
    for d, w, term in runs:
        note(f"runs: {d:g} s fed, warm-up {w:g} s, {term}")
    for a, b in train:
        note(f"training seeds: {a:,}-{b:,} (reset(options={{'line_seed': k}}))")
    note("score a policy: pnp-twin task score TASK --policy P [--seeds N] [--json]")


@task_app.command("score")
def task_score(
    task: Annotated[str, typer.Argument(metavar="TASK", help="A task (see `pnp-twin task list`).")],
    policy: Annotated[
        str,
        typer.Option(
            "--policy",
            "-p",
            metavar="P",
            help="Rule, per-robot mix, hdqn:DIR, sb3:MODEL.zip or lookahead[:...].",
            show_default=False,
        ),
    ],
    seeds: Annotated[
        int | None,
        typer.Option("--seeds", metavar="N", help="The first N evaluation seeds (default all)."),
    ] = None,
    workers: ProcessesOpt = 1,
    engine: EngineOpt = Engine.fast,
    duration: Annotated[
        float | None,
        typer.Option("--duration", min=1.0, hidden=True, help="Shorter runs (tests only)."),
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the score as one JSON object.")
    ] = False,
) -> None:
    """Score a policy on TASK: mean G with its 95 % interval, and the paired difference to
    the task's best rule (the best of the six on the same seeds)."""
    from pnp_twin.learning.tasks import eval_seeds, get_task, score

    t = get_task(task)
    eval_seeds(t, seeds)  # bad seeds fail before any run
    result = score(t, policy, seeds, engine=engine.value, workers=workers, duration=duration)
    data = result.to_json()
    if as_json:
        typer.echo(dumps_json(data, indent=2))
        return
    s = result.seeds
    b = data["best_rule"]
    typer.echo(
        f"{t.name}: {data['policy']} grips {_f(data['gripping_rate'])} % "
        f"[{_f(data['ci_low'])}, {_f(data['ci_high'])}] (95 % t interval, seeds "
        f"{s[0]}-{s[-1]}, {data['duration']:g} s runs)"
    )
    typer.echo(
        f"{data['policy']} - best rule {b['policy']} ({_f(b['gripping_rate'])} %): "
        f"{_f(data['diff'], True)} points [{_f(data['diff_ci_low'], True)}, "
        f"{_f(data['diff_ci_high'], True)}] (paired 95 % interval)"
    )
    if duration is not None:
        note(f"note: {duration:g} s runs, not the task's {t.duration:g} s: not the task's score")


def _f(x: float, sign: bool = False) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:+.2f}" if sign else f"{x:.2f}"
