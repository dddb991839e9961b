"""pnp-twin: a digital twin of multi-robot conveyor pick-and-place lines, one import package.

The repository's folders install under this one name:

- :mod:`pnp_twin.twin`: the simulation core (scenario, feeder, belt, robots, bins, gateway,
  KPIs, the compiled engine); it imports nothing of ours.
- :mod:`pnp_twin.policies`: answering a decision (rules, mixes, the learned HDQN's inference).
- :mod:`pnp_twin.studies`: sweeps, sizing, rule-mix search and calibration.
- :mod:`pnp_twin.learning`: the Gymnasium / PettingZoo envs and HDQN training.
- :mod:`pnp_twin.reports`: study and training folders to HTML; reads files, never simulates.
- :mod:`pnp_twin.cli`: the ``pnp-twin`` command line on top; nothing imports it.
- ``pnp_twin.scenarios`` and ``pnp_twin.models``: shipped scenario files and trained models.

The core's entry points are re-exported here: ``from pnp_twin import load_scenario, simulate``.
In a checkout the folders are mapped in by :mod:`pnp_twin._checkout` (no symbolic links).
"""

from pnp_twin import _checkout

_checkout.install()

from pnp_twin.twin import (  # noqa: E402 (after the checkout's folders are mapped)
    Decision,
    Policy,
    RobotSpec,
    RunResult,
    Scenario,
    ScenarioError,
    __version__,
    load_scenario,
    simulate,
    with_overrides,
)

__all__ = [
    "Decision",
    "Policy",
    "RobotSpec",
    "RunResult",
    "Scenario",
    "ScenarioError",
    "__version__",
    "load_scenario",
    "simulate",
    "with_overrides",
]
