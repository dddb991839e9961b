"""The one way the fast engine compiles a function (numba, imported here only).

numba keys a cached function on its own source file only: a change in a function it calls
from another file (the kernel, called by the rollouts and the vector env; the arithmetic of
:mod:`pnp_twin.twin.fast.mathlib`, called by the kernel) would leave stale machine code in
the cache. So compiled functions are cached in a folder named after a fingerprint of an
explicit list of source folders: this engine's folder, plus the folder of the module that
defines the function (the learning floor compiles its env code over the kernel): any change
to any of their sources compiles afresh.

Where: ``$NUMBA_CACHE_DIR/pnp_twin`` when set; else this package's ``__pycache__/numba``
when it is writable (a checkout, a user's own install); else the user's cache folder
(``$XDG_CACHE_HOME`` or ``~/.cache``, ``pnp_twin/numba``): a read-only install compiles once
per user. Each fingerprint folder records which engine folder wrote it (``owner.txt``);
only folders this same engine folder wrote under another fingerprint, untouched for
``STALE_AFTER`` seconds (a process of the older sources may still be writing there), are
removed, so two checkouts or installs sharing one cache folder never delete each other's code.
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from numba import njit
from numba.core import config

ENGINE = Path(__file__).resolve().parent
OWNER = "owner.txt"
STALE_AFTER = 600.0  # s without a write before another fingerprint's folder is ours to remove


def fingerprint(folders: Iterable[Path] = ()) -> str:
    """A digest of every ``*.py`` source of the engine folder and of ``folders``."""
    digest = hashlib.sha256()
    for folder in sorted({ENGINE, *(Path(f).resolve() for f in folders)}):
        for path in sorted(folder.glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK)


def cache_root() -> Path:
    """The folder that holds one sub-folder per fingerprint (see the module docstring)."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return Path(given) / "pnp_twin"
    here = ENGINE / "__pycache__" / "numba"
    if _writable(here):
        return here
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return home / "pnp_twin" / "numba"


def _owner(folder: Path) -> str:
    try:
        return (folder / OWNER).read_text(encoding="utf-8").strip()
    except OSError:
        return ""


@functools.cache
def _cache_dir(folders: tuple[Path, ...]) -> str:
    """This fingerprint's cache folder (created); our own other fingerprints removed."""
    root = cache_root()
    here = root / fingerprint(folders)
    here.mkdir(parents=True, exist_ok=True)
    me = str(ENGINE)
    if _owner(here) != me:
        tmp = here / f"{OWNER}.{os.getpid()}.tmp"
        tmp.write_text(me + "\n", encoding="utf-8")
        os.replace(tmp, here / OWNER)
    now = time.time()
    for old in root.iterdir():
        if old == here or not old.is_dir() or _owner(old) != me or not _stale(old, folders):
            continue
        if now - old.stat().st_mtime > STALE_AFTER:
            shutil.rmtree(old, ignore_errors=True)
    return str(here)


def _stale(folder: Path, folders: tuple[Path, ...]) -> bool:
    """Whether ``folder`` holds code of the same functions (same defining folders) as
    ``folders`` under an older fingerprint: only those are ours to replace."""
    marker = folder / "folders.txt"
    try:
        listed = marker.read_text(encoding="utf-8").split("\n")
    except OSError:
        return not folders  # written before the marker existed: the engine's own
    return [s for s in listed if s] == [str(f) for f in folders]


def _mark(here: str, folders: tuple[Path, ...]) -> None:
    marker = Path(here) / "folders.txt"
    text = "".join(f"{f}\n" for f in folders)
    if not marker.is_file() or marker.read_text(encoding="utf-8") != text:
        tmp = marker.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, marker)


def _cached(**options: Any) -> Callable[[Any], Any]:
    """``njit(cache=True, **options)`` with the cache in the fingerprint's folder (numba
    reads ``config.CACHE_DIR`` when a function is decorated)."""

    def decorate(fn: Any) -> Any:
        source = Path(fn.__code__.co_filename).resolve().parent
        folders = () if source == ENGINE else (source,)
        here = _cache_dir(folders)
        _mark(here, folders)
        before = getattr(config, "CACHE_DIR", "")
        setattr(config, "CACHE_DIR", here)  # noqa: B010 (numba's config is untyped)
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
