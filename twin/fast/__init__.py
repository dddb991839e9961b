"""The fast engine: the SimPy twin's model compiled with numba, event for event identical.

Importing this package is light; numba is imported (and the kernel loaded from its on-disk
cache, or compiled on first use) only when :func:`simulate_fast` first runs. It runs rule
policies and per-robot rule mixes (every rule, SIRO included) under every termination
scheme, with bins, breakdowns, acceleration limits and trace replay. Policies that are
Python objects (the learned HDQN) are not compiled: ``engine="auto"`` runs them on SimPy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from twin.decision import Policy
    from twin.run import RunResult
    from twin.scenario import Scenario

from twin.errors import UserError

ENGINES = ("simpy", "fast", "auto")


class EngineError(UserError):
    """An unknown engine, or the fast engine asked for what it cannot run; one line."""


def pick_engine(engine: str, policy: Policy) -> str:
    """The engine that runs ``policy``: "fast" or "simpy" (``auto`` falls back to SimPy)."""
    if engine not in ENGINES:
        raise EngineError(f"engine: {engine!r} is not an engine; allowed {', '.join(ENGINES)}")
    if engine == "simpy":
        return "simpy"
    reason = unsupported_reason(policy)
    if reason is None:
        return "fast"
    if engine == "fast":
        raise EngineError(reason)
    return "simpy"


def unsupported_reason(policy: Policy) -> str | None:
    """None if the fast engine can run ``policy``, else one line saying why not."""
    cls = type(policy)
    if cls.__name__ == "RuleMix" and cls.__module__ == "policies.base":
        return None
    return (
        f"engine fast: policy {getattr(policy, 'name', cls.__name__)!r} is a Python object, "
        "not a rule or rule mix; use engine simpy (or auto, which falls back to it)"
    )


def simulate_fast(
    scenario: Scenario, policy: Policy, seed: int | None = None, policy_name: str | None = None
) -> RunResult:
    """:func:`twin.run.simulate` on the compiled engine (rule mixes only)."""
    from twin.fast.run import simulate_fast as run

    return run(scenario, policy, seed=seed, policy_name=policy_name)


def __getattr__(name: str) -> Any:
    if name == "FastLine":
        from twin.fast.engine import FastLine

        return FastLine
    raise AttributeError(name)
