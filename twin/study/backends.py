"""Where runs execute: in-process, a local process pool, or Ray tasks.

Every backend calls the same function (:func:`twin.study.execute.execute`) on the same run
specs, and every run's seed is fixed by the plan, so the rows are identical whatever the
backend, the worker count or the order in which runs finish. Results are handed to
``on_row`` in the coordinating process as they arrive (the journal writes them there).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

from twin.study.execute import execute
from twin.study.plan import RunSpec, StudyError

log = logging.getLogger(__name__)

BACKENDS = ("local", "ray")
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
        run_ray(specs, on_row, workers, address)
    elif workers == 1:
        for spec in specs:
            on_row(execute(spec))
    else:
        run_pool(specs, on_row, workers)


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the coordinator, which cancels the queue and exits."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_pool(specs: Sequence[RunSpec], on_row: OnRow, workers: int) -> None:
    """A local process pool; at most ``2 * workers`` runs are queued at a time."""
    # forkserver: workers fork from a clean server that has already imported the twin, so
    # they start fast and never inherit the caller's threads (progress bars, Ray clients)
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["twin.study.execute"])
    pending = iter(specs)
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=_ignore_sigint
    ) as pool:
        running: set[Future[dict[str, Any]]] = set()
        try:
            for spec in pending:
                running.add(pool.submit(execute, spec))
                if len(running) >= 2 * workers:
                    break
            while running:
                finished, running = wait(running, return_when=FIRST_COMPLETED)
                for fut in finished:
                    on_row(fut.result())
                    nxt = next(pending, None)
                    if nxt is not None:
                        running.add(pool.submit(execute, nxt))
        except BaseException:
            for fut in running:
                fut.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def import_ray() -> Any:
    """The ``ray`` module, or a one-line error naming the extra to install."""
    try:
        import ray
    except ImportError:
        raise StudyError(
            "--backend ray: Ray is not installed; install the extra: "
            "pip install 'pnp-twin[distributed]'"
        ) from None
    return ray


def run_ray(specs: Sequence[RunSpec], on_row: OnRow, workers: int, address: str | None) -> None:
    """The study's runs as Ray tasks."""
    ray_map(execute, specs, on_row, workers, address, retries=2)


def ray_map(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    on_result: Callable[[Any], None],
    workers: int,
    address: str | None,
    retries: int = 0,
) -> None:
    """``fn`` on each item as a Ray task (one CPU each), results to ``on_result`` as they
    finish; on the cluster at ``address`` (or RAY_ADDRESS), else on a local Ray."""
    ray = import_ray()
    address = address or os.environ.get("RAY_ADDRESS") or None
    started_here = not ray.is_initialized()
    if started_here:
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.WARNING,
        }
        if address is None and workers > 1:
            kwargs["num_cpus"] = workers
        try:
            ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as e:
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise StudyError(f"--address {address}: cannot connect to Ray: {first}") from None
    log.info("ray: %s", ray.cluster_resources())
    task = ray.remote(fn).options(num_cpus=1, max_retries=retries)
    refs = [task.remote(item) for item in items]
    try:
        while refs:
            ready, refs = ray.wait(refs, num_returns=len(refs), timeout=0.2)
            for ref in ready:
                on_result(ray.get(ref))
    except BaseException:
        for ref in refs:
            ray.cancel(ref, force=True)
        raise
    finally:
        if started_here:
            ray.shutdown()
