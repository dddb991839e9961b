"""Where work runs in parallel: a local process pool or Ray tasks, for studies and training.

One mapper each: :func:`pool_map` (local processes, forkserver) and :func:`ray_map` (Ray
tasks on a cluster or a local Ray). Both call ``fn`` on every item and hand each result to
``on_result`` in the calling process as it arrives; callers make results independent of
the order (seeds fixed per item), so tables do not depend on the backend or worker count.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

from twin.errors import UserError

log = logging.getLogger(__name__)

BACKENDS = ("local", "ray")


class ParallelError(UserError):
    """A backend cannot be used (Ray missing or unreachable); the message is one line."""


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the coordinator, which cancels the queue and exits."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def pool_map(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    on_result: Callable[[Any], None],
    workers: int,
    preload: Sequence[str] = (),
) -> None:
    """``fn`` on each item in a local process pool, results to ``on_result`` as they finish;
    at most ``2 * workers`` items are queued at a time. Workers ignore Ctrl-C (the caller
    cancels the queue) and the pool is shut down on any exception."""
    # forkserver: workers fork from a clean server that has already imported ``preload``, so
    # they start fast and never inherit the caller's threads (progress bars, Ray clients)
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(preload))
    pending = iter(items)
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=_ignore_sigint
    ) as pool:
        running: set[Future[Any]] = set()
        try:
            for spec in pending:
                running.add(pool.submit(fn, spec))
                if len(running) >= 2 * workers:
                    break
            while running:
                finished, running = wait(running, return_when=FIRST_COMPLETED)
                for fut in finished:
                    on_result(fut.result())
                    nxt = next(pending, None)
                    if nxt is not None:
                        running.add(pool.submit(fn, nxt))
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
        raise ParallelError(
            "--backend ray: Ray is not installed; install the extra: "
            "pip install 'pnp-twin[distributed]'"
        ) from None
    return ray


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
            raise ParallelError(f"--address {address}: cannot connect to Ray: {first}") from None
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
