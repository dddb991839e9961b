"""The ``pnp-twin`` command line: the application, its entry point and its commands.

Each command module registers its commands on :data:`app` when imported. They are imported
lazily: ``pnp-twin run ...`` imports only the module of ``run`` (so a one-run command does
not pay for pandas, gymnasium or the study code); anything that lists the commands (``--help``,
a test's ``CliRunner``) imports them all, and ``--help`` lists them in :data:`COMMANDS` order.
"""

from __future__ import annotations

import sys
from importlib import import_module

from pnp_twin.cli.app import app, end_on_sigterm

COMMANDS: dict[str, str] = {
    "run": "run_cmd",
    "validate": "run_cmd",
    "schema": "run_cmd",
    "list": "run_cmd",
    "compare": "compare_cmd",
    "sweep": "study_cmd",
    "size": "study_cmd",
    "mix": "study_cmd",
    "report": "report_cmd",
    "export": "export_cmd",
    "train": "learn_cmd",
    "evaluate": "learn_cmd",
    "calibrate": "calibrate_cmd",
    "capacity": "capacity_cmd",
    "design": "design_cmd",
    "headroom": "headroom_cmd",
    "tune": "tune_cmd",
    "task": "task_cmd",
}
"""Each command and the module (in this package) that registers it, in ``--help`` order."""


def load_commands(names: list[str] | None = None) -> None:
    """Import the modules registering ``names`` (default: every command)."""
    for name in dict.fromkeys(COMMANDS if names is None else names):
        import_module(f"{__name__}.{COMMANDS[name]}")


def _command_name(args: list[str]) -> str | None:
    """The command ``args`` name: the first argument not an option of the root
    (``-v``, ``--verbose``, ``--version``, ``--help`` take no value)."""
    return next((a for a in args if not a.startswith("-")), None)


app.order = list(COMMANDS)
app.loader = load_commands


def main() -> None:
    """Console-script entry point of ``pnp-twin`` (and ``python -m pnp_twin``); SIGTERM
    ends a command as Ctrl-C does, exit code 143 (:func:`~pnp_twin.cli.app.end_on_sigterm`)."""
    end_on_sigterm()
    name = _command_name(sys.argv[1:])
    if name in COMMANDS:
        app.loader = lambda: load_commands([name])
    app()


__all__ = ["COMMANDS", "app", "load_commands", "main"]
