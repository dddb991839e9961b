"""Where a study's runs execute: in-process, a local process pool, or Ray tasks.

Every backend calls the same function (:func:`pnp_twin.studies.execute.execute`) on the same run
specs, and every run's seed is fixed by the plan, so the rows are identical whatever the
backend, the worker count or the order in which runs finish. Results are handed to
``on_row`` in the coordinating process as they arrive (the journal writes them there).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

from pnp_twin.parallel import BACKENDS, pool_map, ray_map
from pnp_twin.studies.execute import execute
from pnp_twin.studies.plan import RunSpec, StudyError

log = logging.getLogger(__name__)

OnRow = Callable[[dict[str, Any]], None]


def run_specs(
    specs: Sequence[RunSpec],
    on_row: OnRow,
    backend: str = "local",
    workers: int = 1,
    address: str | None = None,
) -> None:
    """Execute ``specs`` on ``backend``, calling ``on_row`` with each finished run's row."""
    if backend not in BACKENDS:
        raise StudyError(f"--backend: '{backend}' is not allowed; allowed {', '.join(BACKENDS)}")
    if workers < 1:
        raise StudyError(f"--workers: {workers} is not allowed; give 1 or more")
    if not specs:
        return
    if backend == "ray":
        ray_map(execute, specs, on_row, workers, address, retries=2)
    elif workers == 1:
        for spec in specs:
            on_row(execute(spec))
    else:
        pool_map(execute, specs, on_row, workers, preload=["pnp_twin.studies.execute"])
