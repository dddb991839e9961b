"""pnp-twin: a discrete-event digital twin of multi-robot conveyor pick-and-place lines.

The simulation core (this package, minus the command line) never imports a policy.
"""

from pnp_twin.twin.decision import Decision, Policy, RobotSpec
from pnp_twin.twin.loader import ScenarioError, load_scenario, with_overrides
from pnp_twin.twin.run import RunResult, simulate
from pnp_twin.twin.scenario import Scenario

__version__ = "0.1.0"

__all__ = [
    "Decision",
    "Policy",
    "RobotSpec",
    "RunResult",
    "Scenario",
    "ScenarioError",
    "load_scenario",
    "simulate",
    "with_overrides",
]
