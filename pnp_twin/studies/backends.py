"""Where a study's runs execute: in-process, a local process pool, or Ray tasks.

Every backend calls the same function (:func:`pnp_twin.studies.execute.execute`) on the same run
specs, and every run's seed is fixed by the plan, so the rows are identical whatever the
backend, the worker count or the order in which runs finish. Results are handed to
``on_row`` in the coordinating process as they arrive (the journal writes them there).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Sequence
from typing import Any

from pnp_twin.parallel import BACKENDS, Pool, pool_map, ray_map, ray_session
from pnp_twin.studies.execute import execute, execute_many
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


POOL_WORTH = 1.0  # s of work per worker in a batch below which it runs in-process
CHUNK_MOST = 16  # runs per pool task: fewer trips between processes, a kill loses at most these


def chunks(specs: Sequence[RunSpec], workers: int) -> list[list[RunSpec]]:
    """``specs`` in contiguous chunks, about two per worker (at most :data:`CHUNK_MOST`
    runs each), so every worker stays busy and short runs do not travel one by one."""
    size = max(1, min(CHUNK_MOST, -(-len(specs) // (2 * workers))))
    return [list(specs[i : i + size]) for i in range(0, len(specs), size)]


def _each(rows: Sequence[dict[str, Any]], on_row: OnRow) -> None:
    for row in rows:
        on_row(row)


class Executor:
    """Where every batch of one study runs, opened once for the whole study: one local
    process pool kept between batches (a design or capacity search asks for many small
    batches, and a fresh pool per batch costs more than its runs), or one Ray session.

    Use as a context manager; ``run`` is :func:`run_specs` on the open backend. Rows are
    the same whatever the backend or worker count (seeds are fixed per run)."""

    def __init__(self, backend: str = "local", workers: int = 1, address: str | None = None):
        if backend not in BACKENDS:
            raise StudyError(
                f"--backend: '{backend}' is not allowed; allowed {', '.join(BACKENDS)}"
            )
        if workers < 1:
            raise StudyError(f"--workers: {workers} is not allowed; give 1 or more")
        self.backend = backend
        self.workers = workers
        self.address = address
        self._stack = contextlib.ExitStack()
        self._pool: Pool | None = None
        self._mean_time: float | None = None  # s per run, measured in-process
        self._runs = 0

    def __enter__(self) -> Executor:
        if self.backend == "ray":
            self._stack.enter_context(ray_session(self.workers, self.address))
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.close()

    def run(self, specs: Sequence[RunSpec], on_row: OnRow) -> None:
        """Execute ``specs``, calling ``on_row`` with each finished run's row."""
        if not specs:
            return
        if self.backend == "ray":
            ray_map(execute, specs, on_row, self.workers, self.address, retries=2)
        elif self.workers == 1 or len(specs) == 1:
            for spec in specs:
                on_row(self._timed(execute(spec)))
        else:
            todo = list(specs)
            if self._mean_time is None:  # the first run, in-process, says how long runs take
                on_row(self._timed(execute(todo.pop(0))))
            if (self._mean_time or 0.0) * len(todo) < POOL_WORTH * self.workers:
                for spec in todo:  # a pool's trips would cost more than they save
                    on_row(self._timed(execute(spec)))
                return
            if self._pool is None:  # started on the first batch that needs it, kept
                self._pool = self._stack.enter_context(
                    Pool(self.workers, preload=["pnp_twin.studies.execute"])
                )
            self._pool.map(
                execute_many, chunks(todo, self.workers), lambda rows: _each(rows, on_row)
            )

    def _timed(self, row: dict[str, Any]) -> dict[str, Any]:
        """Keep a running mean of the runs' wall time (what decides the pool)."""
        t = float(row.get("wall_time") or 0.0)
        self._runs += 1
        m = self._mean_time or 0.0
        self._mean_time = m + (t - m) / self._runs
        return row
