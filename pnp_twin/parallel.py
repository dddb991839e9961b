"""Where work runs in parallel: a local process pool or Ray tasks, for studies and training.

One mapper each: :func:`pool_map` (local processes, forkserver) and :func:`ray_map` (Ray
tasks on a cluster or a local Ray). Both call ``fn`` on every item and hand each result to
``on_result`` in the calling process as it arrives; callers make results independent of
the order (seeds fixed per item), so tables do not depend on the backend or worker count.

Workers end with their caller: each pool worker runs a watchdog thread that ends the
worker when the calling process is gone (even after a SIGKILL, which no handler sees), so
no worker, forkserver or resource tracker stays behind holding the caller's pipes. A Ray
address is checked to answer within :data:`CONNECT_TIMEOUT` before Ray is asked to join it.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from functools import partial
from typing import Any

from pnp_twin.twin.errors import UserError

log = logging.getLogger(__name__)

BACKENDS = ("local", "ray")
WATCH_INTERVAL = 0.25  # s between a worker's checks that its caller is still alive
CONNECT_TIMEOUT = 10.0  # s a Ray address has to accept a connection


class ParallelError(UserError):
    """A backend cannot be used (Ray missing or unreachable); the message is one line."""


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (killed, not yet reaped)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            state = f.read().rsplit(")", 1)[1].split()[0]
        return state not in ("Z", "X")
    except FileNotFoundError:
        return False
    except OSError:  # no /proc (not Linux): ask the kernel
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True


def _watch_caller(caller: int) -> None:
    while process_alive(caller):
        time.sleep(WATCH_INTERVAL)
    os._exit(1)  # the caller is gone: nobody will read this worker's result


def _init_worker(caller: int) -> None:
    """Workers leave Ctrl-C to the caller (which cancels the queue and exits) and end
    themselves when the caller is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_caller, args=(caller,), daemon=True).start()


class Pool:
    """A local process pool kept open across batches (forkserver workers that ignore
    Ctrl-C and end with their caller); ``map`` runs one batch. Use as a context manager:
    the pool is shut down on exit, and at once (queued work cancelled) on any exception."""

    def __init__(self, workers: int, preload: Sequence[str] = ()) -> None:
        self.workers = workers
        self.preload = list(preload)
        self._pool: ProcessPoolExecutor | None = None

    def __enter__(self) -> Pool:
        # forkserver: workers fork from a clean server that has already imported ``preload``,
        # so they start fast and never inherit the caller's threads (progress bars, Ray)
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(self.preload)
        self._pool = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=ctx,
            initializer=_init_worker,
            initargs=(os.getpid(),),
        )
        return self

    def __exit__(self, kind: type[BaseException] | None, *rest: object) -> None:
        if self._pool is not None:
            if kind is None:
                self._pool.shutdown(wait=True)
            else:
                self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def map(
        self, fn: Callable[[Any], Any], items: Sequence[Any], on_result: Callable[[Any], None]
    ) -> None:
        """``fn`` on each item, results to ``on_result`` as they finish; at most
        ``2 * workers`` items are queued at a time."""
        pool = self._pool
        if pool is None:
            raise RuntimeError("Pool.map outside its with-block")
        pending = iter(items)
        running: set[Future[Any]] = set()
        try:
            for spec in pending:
                running.add(pool.submit(fn, spec))
                if len(running) >= 2 * self.workers:
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
            self._pool = None
            raise


def pool_map(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    on_result: Callable[[Any], None],
    workers: int,
    preload: Sequence[str] = (),
) -> None:
    """``fn`` on each item in a fresh local process pool (:class:`Pool`), results to
    ``on_result`` as they finish."""
    with Pool(workers, preload) as pool:
        pool.map(fn, items, on_result)


def _indexed(fn: Callable[[Any], Any], job: tuple[int, Any]) -> tuple[int, Any]:
    return job[0], fn(job[1])


def pool_map_ordered(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    workers: int,
    preload: Sequence[str] = (),
    on_result: Callable[[Any], None] | None = None,
) -> list[Any]:
    """:func:`pool_map` with the results returned in the order of ``items`` (whatever the
    order they finish in); ``on_result`` still sees each one as it finishes."""
    results: list[Any] = [None] * len(items)

    def keep(pair: tuple[int, Any]) -> None:
        results[pair[0]] = pair[1]
        if on_result is not None:
            on_result(pair[1])

    pool_map(partial(_indexed, fn), list(enumerate(items)), keep, workers, preload)
    return results


def _call_indexed(job: tuple[int, Callable[[Any], Any], Any]) -> tuple[int, Any]:
    """A Ray task of :func:`ray_map_ordered` (Ray takes functions, not partials)."""
    i, fn, item = job
    return i, fn(item)


def ray_map_ordered(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    workers: int,
    address: str | None,
    on_result: Callable[[Any], None] | None = None,
) -> list[Any]:
    """:func:`ray_map` with the results returned in the order of ``items``."""
    results: list[Any] = [None] * len(items)

    def keep(pair: tuple[int, Any]) -> None:
        results[pair[0]] = pair[1]
        if on_result is not None:
            on_result(pair[1])

    jobs = [(i, fn, item) for i, item in enumerate(items)]
    ray_map(_call_indexed, jobs, keep, workers, address)
    return results


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


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Refuse, in one line, a ``host:port`` (or ``ray://host:port``) address that does not
    accept a TCP connection within ``timeout`` s; Ray itself would retry for minutes."""
    target = address.split("://", 1)[-1]
    host, sep, port = target.rpartition(":")
    if not sep or not (port.isascii() and port.isdigit()):
        return  # "auto" and the like: Ray resolves those itself
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as e:
        why = "timed out" if isinstance(e, TimeoutError) else (e.strerror or str(e))
        raise ParallelError(
            f"--address {address}: cannot connect to Ray ({why} within {timeout:g} s); "
            "check the address and that the cluster is running"
        ) from None


@contextlib.contextmanager
def ray_session(workers: int, address: str | None) -> Iterator[Any]:
    """Ray, connected for the length of the with-block (the cluster at ``address`` or
    RAY_ADDRESS, else a local Ray of ``workers`` CPUs); shut down at the end if started
    here. Every :func:`ray_map` inside it reuses the session instead of starting its own."""
    ray = import_ray()
    address = address or os.environ.get("RAY_ADDRESS") or None
    started_here = not ray.is_initialized()
    # ray.init installs its own SIGTERM handler in the caller; put the caller's back at the end
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    if started_here:
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.WARNING,
        }
        if address is None and workers > 1:
            kwargs["num_cpus"] = workers
        if address is not None:
            check_reachable(address)
        try:
            ray.init(address=address, **kwargs)
        except BaseException as e:
            _restore_handlers(handlers)
            if not isinstance(e, ConnectionError | RuntimeError | ValueError):
                raise
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise ParallelError(f"--address {address}: cannot connect to Ray: {first}") from None
    try:
        yield ray
    finally:
        if started_here:
            ray.shutdown()
            _restore_handlers(handlers)


def ray_map(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    on_result: Callable[[Any], None],
    workers: int,
    address: str | None,
    retries: int = 0,
) -> None:
    """``fn`` on each item as a Ray task (one CPU each), results to ``on_result`` as they
    finish; on the cluster at ``address`` (or RAY_ADDRESS), else on a local Ray (within a
    :func:`ray_session`, on its session)."""
    with ray_session(workers, address) as ray:
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


def _restore_handlers(handlers: dict[signal.Signals, Any]) -> None:
    """Put back signal handlers saved with ``signal.getsignal`` (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for s, handler in handlers.items():
        if handler is not None and signal.getsignal(s) is not handler:
            signal.signal(s, handler)
