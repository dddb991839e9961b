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
import shutil
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import tomli_w

from pnp_twin.twin.errors import UserError, clip
from pnp_twin.twin.inputs import file_kind

if TYPE_CHECKING:
    import pandas as pd

TABLE_SUFFIXES = (".csv", ".parquet")
TEMPORARY = re.compile(r"\..+\.[0-9a-f]{12}\.tmp")  # atomic_path's names: .NAME.HEX.tmp


class OutputError(UserError):
    """A result file that cannot be written where or how the user asked; one line."""


def _existing_ancestor(p: Path) -> Path:
    """The nearest folder above ``p`` (or ``p``'s parent) that exists."""
    q = p.absolute().parent
    while not q.exists() and q != q.parent:
        q = q.parent
    return q


def check_writable(path: str | Path, option: str = "output") -> Path:
    """``path`` as a Path if it can be written: not a folder or another kind of non-regular
    file, and its nearest existing folder writable. Nothing is created here (a missing parent
    folder is made when the file is written), so a command refused later leaves no trace.

    Called before a long computation, so a bad output path fails at once, not at the end.
    """
    p = Path(path)
    kind = file_kind(p)
    if kind == "a folder":
        raise OutputError(f"{option}: '{p}' is a folder; give a file name")
    if kind is not None:
        raise OutputError(f"{option}: '{p}' is {kind}; give a regular file name")
    base = _existing_ancestor(p)
    if not base.is_dir():
        raise OutputError(f"{option}: cannot create folder '{p.parent}': '{base}' is a file")
    if not os.access(base, os.W_OK):
        raise OutputError(f"{option}: cannot write in folder '{base}': permission denied")
    return p


def same_path(a: str | Path, b: str | Path) -> bool:
    """Whether two paths name one file: equal once links and ``..`` are resolved, or (both
    existing) the same inode, so a hard link counts too."""
    try:
        if Path(a).resolve() == Path(b).resolve():
            return True
        return os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_not_inputs(
    output: str | Path, inputs: Mapping[str, str | Path | None], option: str
) -> None:
    """Refuse an output file that is one of the command's input files (``inputs``: what
    each is -> its path), before anything is written: no output overwrites an input."""
    for what, path in inputs.items():
        if path is not None and same_path(output, path):
            raise OutputError(
                f"{option}: '{clip(str(output))}' is the {what} this command reads; writing "
                "there would overwrite it; give another file"
            )
        if path is not None and _inside(output, path):
            raise OutputError(
                f"{option}: '{clip(str(output))}' lies inside the {_folder(what)} "
                f"'{clip(str(path))}' this command reads; writing there would change its "
                "inputs; give a file elsewhere"
            )


def _folder(what: str) -> str:
    """``what`` named as a folder once: "trace folder", "policy folder"."""
    return what if "folder" in what else f"{what} folder"


def _inside(output: str | Path, folder: str | Path) -> bool:
    """Whether ``output`` lies inside the existing folder ``folder`` (links resolved)."""
    f = Path(folder)
    if not f.is_dir():
        return False
    root, out = f.resolve(), Path(output).resolve()
    return root in out.parents


def check_out_folder(
    out: str | Path,
    inputs: Mapping[str, str | Path | None],
    ours: Iterable[str],
    option: str = "--out",
) -> Path:
    """Check an output folder before it is created: not a file, not a folder that holds
    files and is not one of ours (one of ``ours`` names an entry in it: a study to resume),
    not a folder holding one of the command's ``inputs`` (a study rewrites its folder)."""
    p = Path(out)
    kind = file_kind(p)
    if kind is not None and kind != "a folder":
        raise OutputError(f"{option} {clip(str(p))}: is {kind}; give a folder")
    if p.exists() and not p.is_dir():
        raise OutputError(f"{option} {clip(str(p))}: is a file; give a folder")
    base = _existing_ancestor(p / "x")
    if not base.is_dir():
        raise OutputError(f"{option} {clip(str(p))}: cannot be created; '{base}' is a file")
    root = p.resolve()
    for what, path in inputs.items():
        if path is None:
            continue
        q = Path(path).resolve()
        if q.is_dir() and (q == root or q in root.parents):
            raise OutputError(
                f"{option} {clip(str(p))}: lies inside the {_folder(what)} '{clip(str(path))}' "
                "this command reads; writing there would change its inputs; choose another "
                "folder"
            )
        if q == root or root in q.parents:
            raise OutputError(
                f"{option} {clip(str(p))}: holds the {what} '{clip(str(path))}' this command "
                "reads; the study writes into its folder, so keep inputs outside it or choose "
                "another folder"
            )
    if p.is_dir():
        try:
            entries = {e.name for e in os.scandir(p)}
        except OSError as e:
            raise OutputError(f"{option} {clip(str(p))}: cannot be read: {e.strerror}") from None
        if entries and not entries & set(ours):
            shown = ", ".join(sorted(entries)[:3]) + (", ..." if len(entries) > 3 else "")
            raise OutputError(
                f"{option} {clip(str(p))}: is a folder that holds other files ({clip(shown, 50)}) "
                "and no study of ours; give an empty or new folder, or a study folder to resume"
            )
        if not os.access(p, os.W_OK):
            raise OutputError(f"{option} {clip(str(p))}: cannot be written: permission denied")
    elif not os.access(base, os.W_OK):
        raise OutputError(
            f"{option} {clip(str(p))}: cannot be created in '{base}': permission denied"
        )
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


LOCK_NAMES = frozenset({".study.lock", ".study.lock.json", ".pnp-twin.json", "study.json"})
"""What a command writes into a folder before its first result: a folder it created that
holds only these (and empty files) when it is refused is removed again."""


@contextmanager
def removed_if_refused(out: str | Path, only: frozenset[str] = LOCK_NAMES) -> Iterator[None]:
    """Remove the folder ``out`` again when the block created it and fails before writing
    any file in it but those named in ``only`` (a study's lock): a refusal leaves nothing."""
    folder = Path(out)
    existed = folder.exists()
    try:
        yield
    except BaseException:
        if not existed and folder.is_dir():
            files = [p for p in folder.rglob("*") if not p.is_dir()]
            if all(p.name in only or _empty(p) for p in files):
                shutil.rmtree(folder, ignore_errors=True)
        raise


def _empty(path: Path) -> bool:
    """A file that holds no result: empty, a store's side file, or a store with no row."""
    try:
        if path.stat().st_size == 0 or path.name.endswith((".sqlite-wal", ".sqlite-shm")):
            return True
    except OSError:
        return False
    return path.suffix == ".sqlite" and _no_rows(path)


def _no_rows(path: Path) -> bool:
    import sqlite3

    try:
        db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            tables = [r[0] for r in db.execute("select name from sqlite_master where type='table'")]
            return all(db.execute(f'select count(*) from "{t}"').fetchone()[0] == 0 for t in tables)
        finally:
            db.close()
    except sqlite3.Error:
        return False


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
