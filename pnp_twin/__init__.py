"""pnp-twin's upper floors: studies, learning and the command line, over the core.

- :mod:`twin`: the simulation core (scenario, feeder, belt, robots, bins, gateway, KPIs);
  it imports nothing of ours.
- :mod:`policies`: answering a decision (rules, mixes, the learned HDQN); imports ``twin``.
- :mod:`pnp_twin.studies`: sweeps, sizing and rule-mix search; imports the two above.
- :mod:`pnp_twin.learning`: the Gymnasium / PettingZoo envs and HDQN training.
- :mod:`reports`: study and training folders to HTML; reads files, never simulates.
- :mod:`pnp_twin.cli`: the ``pnp-twin`` command line on top; nothing imports it.
"""

from twin import __version__

__all__ = ["__version__"]
