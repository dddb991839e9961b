"""The ``pnp-twin`` command line: the application, its entry point and its commands.

Each command module registers its commands on :data:`app` when imported here.
"""

from twin.cli import run_cmd  # noqa: F401  (registers run, validate, schema, list)
from twin.cli.app import app, main

# Command modules written by other parts of the project are imported here too, e.g.
# ``study_cmd`` (sweep, size, mix), ``report_cmd`` (report) and ``learn_cmd`` (train,
# evaluate); the lead adds those lines as the modules land.

__all__ = ["app", "main"]
