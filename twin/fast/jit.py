"""The one way the fast engine compiles a function (numba, imported here only).

numba keys a cached function on its own source file only: a change in a function it calls
from another file (the kernel, called by the rollouts and the vector env; the arithmetic of
:mod:`twin.fast.mathlib`, called by the kernel) would leave stale machine code in the cache.
So the engine's functions are cached in a folder named after a fingerprint of all of the
engine's sources: any change to any of them compiles afresh. The folder lies under
``$NUMBA_CACHE_DIR`` when set, else in this package's ``__pycache__`` (or, where that is not
writable, the user's cache folder); folders of other fingerprints there are removed.
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from numba import njit
from numba.core import config

ENGINE = Path(__file__).resolve().parent


def fingerprint() -> str:
    """A digest of every source file of the engine (this folder's ``*.py``)."""
    digest = hashlib.sha256()
    for path in sorted(ENGINE.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK)


@functools.cache
def _cache_dir() -> str:
    """This fingerprint's cache folder (created), the other fingerprints' removed."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        root = Path(given) / "pnp_twin"
    else:
        root = ENGINE / "__pycache__" / "numba"
        if not _writable(root):
            home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
            root = home / "pnp_twin" / "numba"
    here = root / fingerprint()
    here.mkdir(parents=True, exist_ok=True)
    for old in root.iterdir():
        if old != here and old.is_dir():
            shutil.rmtree(old, ignore_errors=True)
    return str(here)


def _cached(**options: Any) -> Callable[[Any], Any]:
    """``njit(cache=True, **options)`` with the cache in the fingerprint's folder (numba
    reads ``config.CACHE_DIR`` when a function is decorated)."""

    def decorate(fn: Any) -> Any:
        before = getattr(config, "CACHE_DIR", "")
        setattr(config, "CACHE_DIR", _cache_dir())  # noqa: B010 (numba's config is untyped)
        try:
            return njit(cache=True, **options)(fn)
        finally:
            setattr(config, "CACHE_DIR", before)  # noqa: B010

    return decorate


def compiled(inline: bool = False, parallel: bool = False) -> Any:
    """``numba.njit`` as the engine uses it: cached on disk (see the module docstring); the
    numpy error model (no division checks: the twin never divides by zero); no reference
    counting (the kernel allocates nothing, so array arguments cost nothing to pass); small
    helpers inlined. ``parallel``: ``prange`` loops run on numba's threads (these keep
    reference counting, which numba's parallel loops need)."""
    if parallel:
        return _cached(error_model="numpy", parallel=True)
    extra = {"inline": "always"} if inline else {}
    return _cached(error_model="numpy", _nrt=False, **extra)
