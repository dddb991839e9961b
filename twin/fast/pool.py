"""Buffers reused from run to run, so a run's arrays do not page-fault fresh memory in.

A run's large arrays (the records, the parts' state, the span buffer, the KPIs' scratch)
cost more to fault into memory, page by page, than to fill. :func:`take` hands out the
memory of the previous array of the same role (``"holder"``, ``"sp_f"``...) when nothing
refers to that array any more (its reference count says so, as ``ndarray.resize``'s
``refcheck`` tells), and a new array otherwise. So an array that is still reachable (a
RunResult's tables, a user's view, a fork, an environment's line) is never reused; memory a
run let go is, the way ``free`` and ``malloc`` would, without returning it to the system in
between. One buffer per role is kept (the last one), so the pool holds about one run's
arrays; a buffer more than four times what a role needs is replaced.
"""

from __future__ import annotations

import sys
import threading
from math import prod

import numpy as np

_BUFFERS: dict[str, np.ndarray] = {}
_LOCK = threading.Lock()  # one taker at a time: two threads never get the same buffer


def _free_count() -> int:
    """The reference count :func:`take` reads of a buffer only the pool refers to (its
    entry, the local name and ``getrefcount``'s argument), measured the same way."""
    probe = {"probe": np.empty(0)}
    buf = probe["probe"]
    return sys.getrefcount(buf)


_FREE = _free_count()


def take(
    role: str, shape: int | tuple[int, ...], dtype: type | np.dtype = np.float64
) -> np.ndarray:
    """An uninitialised C-contiguous array of ``shape`` and ``dtype`` (a view of the role's
    buffer: the buffer stays referred to while the array or any view of it lives)."""
    shape = (shape,) if isinstance(shape, int) else tuple(shape)
    size = prod(shape)
    dt = np.dtype(dtype)
    with _LOCK:
        buf = _BUFFERS.get(role)
        if (
            buf is None
            or buf.dtype != dt
            or buf.size < size
            or buf.size > 4 * size + 4096
            or sys.getrefcount(buf) != _FREE
        ):
            buf = np.empty(max(size, 1), dtype=dt)
            _BUFFERS[role] = buf
        return buf[:size].reshape(shape)


def clear() -> None:
    """Let every kept buffer go (a memory measure that should count a run's whole arrays
    calls it first; the next runs allocate afresh)."""
    with _LOCK:
        _BUFFERS.clear()
