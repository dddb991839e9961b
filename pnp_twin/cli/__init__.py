"""The ``pnp-twin`` command line: the application, its entry point and its commands.

Each command module registers its commands on :data:`app` when imported here, in the order
``--help`` lists them.
"""

from pnp_twin.cli.app import app, main

# isort: off
from pnp_twin.cli import run_cmd  # noqa: F401  (registers run, validate, schema, list)
from pnp_twin.cli import study_cmd  # noqa: F401  (registers sweep, size, mix)
from pnp_twin.cli import report_cmd  # noqa: F401  (registers report)
from pnp_twin.cli import export_cmd  # noqa: F401  (registers export)
from pnp_twin.cli import learn_cmd  # noqa: F401  (registers train, evaluate)
from pnp_twin.cli import calibrate_cmd  # noqa: F401  (registers calibrate)
# isort: on

__all__ = ["app", "main"]
