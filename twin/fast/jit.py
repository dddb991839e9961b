"""The one way the fast engine compiles a function (numba, imported here only)."""

from __future__ import annotations

from typing import Any

from numba import njit


def compiled(inline: bool = False, parallel: bool = False) -> Any:
    """``numba.njit`` as the engine uses it: cached on disk; the numpy error model (no
    division checks: the twin never divides by zero); no reference counting (the kernel
    allocates nothing, so array arguments cost nothing to pass); small helpers inlined.
    ``parallel``: ``prange`` loops run on numba's threads (these keep reference counting,
    which numba's parallel loops need)."""
    if parallel:
        return njit(cache=True, error_model="numpy", parallel=True)
    extra = {"inline": "always"} if inline else {}
    return njit(cache=True, error_model="numpy", _nrt=False, **extra)  # type: ignore[call-overload]
