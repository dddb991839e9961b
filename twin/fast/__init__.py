"""The fast engine: the SimPy twin's model compiled with numba, event for event identical.

``twin.run.simulate(..., engine="fast" | "auto")`` runs here. Importing this package is
light; numba is imported (and the kernel loaded from its on-disk cache, or compiled on first
use, about 14 s of CPU) only when a fast run starts. It runs rule policies and per-robot rule
mixes (every rule, SIRO included: numpy's ``Generator.integers`` is replayed on the policy
stream's pre-drawn raw outputs) under every termination scheme, with bins and box changes,
breakdowns, acceleration limits and trace replay. Policies that are Python objects (the
learned HDQN, any other ``choose``) are called back at their decisions: the kernel stops,
the policy gets the SimPy gateway's own :class:`~twin.decision.Decision` (and, through
``attach``, a :class:`~twin.fast.belt_view.BeltView` of the belt), and the run resumes.

Modules: :mod:`~twin.fast.mathlib` (CPython's float operations, bit for bit),
:mod:`~twin.fast.layout` (state array columns), :mod:`~twin.fast.structs` (the arrays in
five named structures: parameters, state, records, streams, scratch, as every kernel function
takes them), :mod:`~twin.fast.kernel` (the event loop),
:mod:`~twin.fast.calendar` (its event calendar), :mod:`~twin.fast.robot` and
:mod:`~twin.fast.gateway` (the robot's steps, the gateway's epochs),
:mod:`~twin.fast.tally` (the KPIs' sums in one compiled pass),
:mod:`~twin.fast.engine` (:class:`FastLine`: a run as arrays; ``start``/``advance``/``fork``
copy a run at any instant; ``kpi_records`` hands its arrays to :mod:`twin.kpis`),
:mod:`~twin.fast.belt_view` (the belt as attached policies read it),
:mod:`~twin.fast.run` (the RunResult), :mod:`~twin.fast.rollouts` (every choice x sampled
future continued from a forked decision in one compiled call: rollout labelling),
the vector environment's engine (many lines in hold mode stepped in one compiled call over
this kernel) lives on the learning floor, :mod:`pnp_twin.learning.vector`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pnp_twin.twin.decision import Policy
    from pnp_twin.twin.result import RunResult
    from pnp_twin.twin.scenario import Scenario

from pnp_twin.twin.errors import UserError

ENGINES = ("simpy", "fast", "auto")


class EngineError(UserError):
    """An unknown engine; one line."""


def pick_engine(engine: str, policy: Policy) -> str:
    """The engine that runs ``policy``: "fast" or "simpy". The fast engine runs every
    policy (Python objects through a callback at their decisions), so ``auto`` is "fast"."""
    if engine not in ENGINES:
        raise EngineError(f"engine: {engine!r} is not an engine; allowed {', '.join(ENGINES)}")
    return "simpy" if engine == "simpy" else "fast"


def simulate_fast(
    scenario: Scenario, policy: Policy, seed: int | None = None, policy_name: str | None = None
) -> RunResult:
    """:func:`twin.run.simulate` on the compiled engine."""
    from pnp_twin.twin.fast.run import simulate_fast as run

    return run(scenario, policy, seed=seed, policy_name=policy_name)


def prepare() -> None:
    """Compile the kernel now (or load it from the on-disk cache). A study calls this once
    before it starts worker processes, so that they load the kernel instead of each
    compiling it (about 14 s of CPU, once per installation)."""
    from pnp_twin.twin.fast.engine import FastLine
    from pnp_twin.twin.scenario import Scenario

    line = FastLine(Scenario(duration=1.0, warmup=0.0), rules=["SIRO"])
    line.run()
    line.kpis(0.0)  # the KPIs' compiled pass too


def __getattr__(name: str) -> Any:
    if name == "FastLine":
        from pnp_twin.twin.fast.engine import FastLine

        return FastLine
    raise AttributeError(name)
