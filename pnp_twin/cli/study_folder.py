"""What every study-like command (``design``, ``capacity``) does around its work: check the
policies and the output folder before anything is written, then run holding the folder's
lock."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TypeVar

from pnp_twin.cli.claim import Inputs, claim_folder
from pnp_twin.policies import make_policy
from pnp_twin.twin.loader import with_overrides
from pnp_twin.twin.scenario import Scenario

T = TypeVar("T")


def check_policies(policies: Iterable[str], n_robots: int) -> None:
    """Each policy spec builds for the line (a PolicyError, one line, otherwise)."""
    for spec in policies:
        make_policy(spec, n_robots)


def with_duration(scenario: Scenario, duration: float | None) -> Scenario:
    """``scenario`` fed for ``duration`` s (``--duration``), its warm-up at most a fifth of
    that; as it is when None."""
    if duration is None:
        return scenario
    warmup = min(scenario.warmup, duration / 5.0)
    return with_overrides(scenario, {"duration": duration, "warmup": warmup})


def run_locked(out: Path, kind: str, inputs: Inputs, work: Callable[[str], T]) -> T:
    """Claim ``out`` for a ``kind`` command (:func:`~pnp_twin.cli.claim.claim_folder`:
    checked, locked, its kind recorded), then run ``work(command)`` in it."""
    with claim_folder(out, kind, inputs) as command:
        return work(command)
