"""Writing results to files: tables (CSV or Parquet by suffix), JSON and text, atomically.

Every writer goes through a temporary file in the target's folder and ``os.replace``, so a
reader never sees a half-written file and an interrupted run leaves the old file intact. A
missing parent folder is created. Mistakes in a user-given path (an unknown table suffix, a
folder that cannot be written) raise :class:`OutputError`, whose message is one line.
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
import secrets
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import tomli_w

from pnp_twin.twin.errors import UserError

if TYPE_CHECKING:
    import pandas as pd

TABLE_SUFFIXES = (".csv", ".parquet")
TEMPORARY = re.compile(r"\..+\.[0-9a-f]{12}\.tmp")  # atomic_path's names: .NAME.HEX.tmp


class OutputError(UserError):
    """A result file that cannot be written where or how the user asked; one line."""


def check_writable(path: str | Path, option: str = "output") -> Path:
    """``path`` as a Path once its folder exists (created if missing) and can be written.

    Called before a long computation, so a bad output path fails at once, not at the end.
    """
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{option}: '{p}' is a folder; give a file name")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"{option}: cannot create folder '{p.parent}': {e.strerror}") from None
    if not os.access(p.parent, os.W_OK):
        raise OutputError(f"{option}: cannot write in folder '{p.parent}': permission denied")
    return p


def check_table_path(path: str | Path, option: str = "output") -> Path:
    """``path`` as a Path if its suffix names a table format and it can be written."""
    p = Path(path)
    if p.suffix.lower() not in TABLE_SUFFIXES:
        raise OutputError(
            f"{option}: '{p}' has suffix '{p.suffix}'; allowed {', '.join(TABLE_SUFFIXES)}"
        )
    return check_writable(p, option)


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two output paths name one file (after resolving links and ``..``)."""
    return Path(a).resolve() == Path(b).resolve()


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` to write; on success it replaces ``path``."""
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.parent / f".{target.name}.{secrets.token_hex(6)}.tmp"  # see TEMPORARY
        # os.open, not mkstemp: the file gets the usual permissions (0666 less the umask)
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    except OSError as e:
        raise OutputError(f"cannot write '{target}': {e.strerror or e}") from None
    try:
        yield tmp
        os.replace(tmp, target)
    except OSError as e:
        raise OutputError(f"cannot write '{target}': {e.strerror or e}") from None
    finally:
        tmp.unlink(missing_ok=True)


def write_text(text: str, path: str | Path) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_json(
    obj: Any, path: str | Path, indent: int | None = 2, *, keep_nan: bool = False
) -> Path:
    """Write ``obj`` as JSON atomically; return the path.

    By default the JSON is strict: NaN and infinities become null. With ``keep_nan`` they
    are written as ``NaN`` / ``Infinity`` (which Python's ``json`` reads back), so records
    such as a study's journal rows round-trip exactly.
    """
    return write_text(dumps_json(obj, indent, keep_nan=keep_nan) + "\n", path)


def write_table(df: pd.DataFrame, path: str | Path, option: str = "output") -> Path:
    """Write ``df`` as CSV or Parquet, chosen by the suffix of ``path``, atomically."""
    p = Path(path)
    if p.suffix.lower() not in TABLE_SUFFIXES:
        check_table_path(p, option)
    writers: dict[str, Callable[[Path], Any]] = {
        ".csv": lambda tmp: df.to_csv(tmp, index=False),
        ".parquet": lambda tmp: df.to_parquet(tmp, index=False),
    }
    with atomic_path(p) as tmp:
        writers[p.suffix.lower()](tmp)
    return p


def jsonable(obj: Any, keep_nan: bool = False) -> Any:
    """``obj`` with numpy scalars made plain, paths as text, and NaN / infinities replaced
    by None (kept as they are with ``keep_nan``)."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v, keep_nan) for k, v in obj.items()}
    if isinstance(obj, list | tuple | np.ndarray):
        return [jsonable(v, keep_nan) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj) and not keep_nan:
        return None
    pandas = sys.modules.get("pandas")  # pd.NA exists only if pandas was imported
    if pandas is not None and obj is pandas.NA:
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def dumps_json(obj: Any, indent: int | None = None, keep_nan: bool = False) -> str:
    """JSON text of ``obj`` (see :func:`jsonable`); strict unless ``keep_nan``."""
    return json.dumps(jsonable(obj, keep_nan), indent=indent, allow_nan=keep_nan)


def versions(*distributions: str) -> dict[str, str]:
    """The Python version and each installed distribution's, for a result's provenance.

    Keys are import-style names (``pnp-twin`` -> ``pnp_twin``); a missing one is "unknown".
    """
    out = {"python": platform.python_version()}
    for dist in distributions:
        try:
            out[dist.replace("-", "_")] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist.replace("-", "_")] = "unknown"
    return out


def is_temporary(path: Path) -> bool:
    """Whether ``path`` is a temporary file of :func:`atomic_path` (``.NAME.HEX.tmp``)."""
    return TEMPORARY.fullmatch(path.name) is not None


def remove_temporaries(folder: str | Path) -> list[Path]:
    """Delete the temporary files an interrupted write left in ``folder``; return them.

    Only the caller knows that no write of its own is still running there (a study holds
    its folder's lock when it calls this).
    """
    removed = []
    for p in Path(folder).glob(".*.tmp"):
        if p.is_file() and is_temporary(p):
            p.unlink(missing_ok=True)
            removed.append(p)
    return removed


def dumps_toml(data: Mapping[str, Any]) -> str:
    """TOML text of a nested mapping; ``None`` values are left out (TOML has no null)."""
    return tomli_w.dumps(_toml_ready(data))


def _toml_ready(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Mapping):
        return {str(k): _toml_ready(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_toml_ready(v) for v in value]
    return value
