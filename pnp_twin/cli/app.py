"""The ``pnp-twin`` application object and its entry point, with one-line user errors.

Commands live in their own modules (``run_cmd``, and others added by later parts) and
register themselves on :data:`app`. Whatever the command, a user mistake (any
:class:`twin.errors.UserError`, an unreadable or unwritable user-given path, a bad option)
ends the program with ``error: <one line>`` on stderr and exit code 2, never a traceback;
Ctrl-C ends it with exit code 130.
"""

from __future__ import annotations

import errno
import logging
import os
import signal
import sys
from collections.abc import Callable, Sequence
from enum import StrEnum
from typing import Annotated, Any, NoReturn

import typer
from typer.core import TyperGroup

from pnp_twin import __version__
from pnp_twin.policies.user_guard import TIMEOUT_ENV
from pnp_twin.twin.errors import UserError

USER_ERROR = 2
INTERRUPTED = 130
TERMINATED = 143  # 128 + SIGTERM, as a shell reports a process ended by it


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, ``timeout``, a job scheduler): unwinds like Ctrl-C, so a study
    writes its buffered journal rows and lets go of its folder before it ends."""


class Engine(StrEnum):
    """Simulation engines (``twin.run.simulate``): identical events, different speed."""

    simpy = "simpy"
    fast = "fast"
    auto = "auto"


# Arguments and options shared by the command modules (each command sets the default).
ScenarioArg = Annotated[
    str,
    typer.Argument(
        metavar="SCENARIO",
        help="A scenario file (.toml, .yaml) or the name of a shipped one (see `pnp-twin list`).",
        show_default=False,
    ),
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        metavar="PATH=VALUE",
        help="Override a scenario field, e.g. --set robots.arm_speed=4 (repeatable).",
    ),
]
WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        "-w",
        min=1,
        max=1024,
        help="Parallel runs (1 = in-process). Default: CPU count.",
    ),
]
EngineOpt = Annotated[
    Engine,
    typer.Option(
        "--engine",
        help="Simulation engine: simpy, fast (compiled) or auto (fast where it can); the "
        "results are identical.",
    ),
]
FreshOpt = Annotated[
    bool, typer.Option("--fresh", help="Discard the folder's earlier runs and start over.")
]
NoReportOpt = Annotated[bool, typer.Option("--no-report", help="Do not write report.html.")]
ForceOpt = Annotated[
    bool, typer.Option("--force", help="Run even above the work limits (twin.budget).")
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]
ProcessesOpt = Annotated[int, typer.Option("--workers", min=1, max=256, help="Worker processes.")]
"""``--workers`` of the commands that run a policy on many seeds (headroom, tune, task)."""
RunDurationOpt = Annotated[
    float | None,
    typer.Option(
        "--duration",
        min=1.0,
        help="Feeding time per run, s (default the scenario's); the warm-up is then at most "
        "a fifth of it.",
    ),
]
"""``--duration`` of the commands that run a policy on many seeds (headroom, tune): see
:func:`pnp_twin.cli.study_folder.with_duration`."""
KpiOpt = Annotated[
    str,
    typer.Option(
        "--kpi",
        metavar="gripping_rate|value_rate|gripping_rate:KIND",
        help="The figure the target is on (headroom: the one compared) and the answer reports: "
        "gripping_rate (G), "
        "value_rate (% of the value presented that is gripped; on a line without "
        "feeder.kinds every part has the same value, so it is G) or gripping_rate:KIND (one "
        "kind of feeder.kinds that some robot picks).",
    ),
]


def fail(message: str, code: int = USER_ERROR) -> NoReturn:
    """Print ``error: message`` as one line on stderr and exit with ``code``."""
    line = " ".join(str(message).split()) or "unknown error"
    typer.echo(f"error: {line}", err=True)
    raise typer.Exit(code)


def os_error_message(e: OSError) -> str:
    """One line for an OSError on a user-given path."""
    where = f"'{e.filename}': " if e.filename else ""
    return f"cannot access {where}{e.strerror or e}"


class OneLineErrors(TyperGroup):
    """A command group that turns user mistakes into one line and a clean exit code."""

    def invoke(self, ctx: typer.Context) -> Any:  # type: ignore[override]
        try:
            return super().invoke(ctx)
        except UserError as e:
            fail(str(e))
        except OSError as e:
            if e.errno == errno.EPIPE:  # stdout closed early (`| head`): not a user mistake
                raise
            fail(os_error_message(e))
        except Terminated:
            fail("terminated", TERMINATED)
        except KeyboardInterrupt:
            fail("interrupted", INTERRUPTED)

    def main(  # type: ignore[override]
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        """Run the group; usage errors (bad option, missing argument) also become one line."""
        try:
            result = super().main(
                args=args,
                prog_name=prog_name or "pnp-twin",
                complete_var=complete_var,
                standalone_mode=False,
                **extra,
            )
        except typer.TyperException as e:  # bad option or argument: a usage error, code 2
            code = _report(e.format_message(), e.exit_code)
        except typer.Abort:
            code = _report("interrupted", INTERRUPTED)
        except Terminated:
            code = _report("terminated", TERMINATED)
        except KeyboardInterrupt:
            code = _report("interrupted", INTERRUPTED)
        else:
            code = result if isinstance(result, int) else 0
            if not standalone_mode:
                return result
        if standalone_mode:
            sys.exit(code)
        return code


def _report(message: str, code: int) -> int:
    line = " ".join(str(message).split()) or "unknown error"
    typer.echo(f"error: {line}", err=True)
    return code


class LazyTyper(typer.Typer):
    """A Typer whose command modules are imported when its commands are first listed.

    ``loader`` (set by :mod:`pnp_twin.cli`) imports the modules that register commands; it
    runs once, the first time Typer reads :attr:`registered_commands`, so ``pnp-twin run``
    imports only ``run_cmd`` and its dependencies, not those of every other command.
    ``order`` keeps ``--help`` listing the commands in the same order whatever was imported
    first.
    """

    loader: Callable[[], None] | None = None
    order: Sequence[str] = ()

    @property  # type: ignore[override]
    def registered_commands(self) -> list[Any]:
        loader, self.loader = self.loader, None
        if loader is not None:
            loader()
        rank = {name: i for i, name in enumerate(self.order)}
        self._commands.sort(key=lambda c: rank.get(c.name, len(rank)))
        return self._commands

    @registered_commands.setter
    def registered_commands(self, value: list[Any]) -> None:
        self._commands = value


app = LazyTyper(
    name="pnp-twin",
    cls=OneLineErrors,
    help="Digital twin of multi-robot conveyor pick-and-place lines.",
    invoke_without_command=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"pnp-twin {__version__}")
        raise typer.Exit()


@app.callback()
def root(
    ctx: typer.Context,
    verbose: Annotated[
        int,
        typer.Option("--verbose", "-v", count=True, help="Log progress to stderr (-vv: debug)."),
    ] = 0,
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
    decision_timeout: Annotated[
        float | None,
        typer.Option(
            "--decision-timeout",
            min=0.0,
            max=86400.0,
            metavar="SECONDS",
            help="Most seconds a py: policy may take over one decision (default 10; 0: no "
            "limit); past it the run stops with one line.",
        ),
    ] = None,
) -> None:
    """Digital twin of multi-robot conveyor pick-and-place lines."""
    if decision_timeout is not None:  # the environment: worker processes read it too
        os.environ[TIMEOUT_ENV] = repr(float(decision_timeout))
    if ctx.invoked_subcommand is None:  # bare `pnp-twin`: show what it can do
        typer.echo(ctx.get_help())
        raise typer.Exit()
    if verbose:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        for name in ("pnp_twin",):
            logger = logging.getLogger(name)
            logger.setLevel(logging.DEBUG if verbose > 1 else logging.INFO)
            logger.handlers = [handler]


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def end_on_sigterm() -> None:
    """SIGTERM ends the command as Ctrl-C does (finished work written, the folder let go),
    with exit code 143; installed by the console-script entry point only."""
    signal.signal(signal.SIGTERM, _terminate)


def main() -> None:
    """Console-script entry point of ``pnp-twin`` (and ``python -m twin``)."""
    end_on_sigterm()
    app()
