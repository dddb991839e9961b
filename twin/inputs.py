"""The one door every user input comes in through: scenario, trace or trace folder, targets,
cost file, policy file, model.

Each reader here checks, before anything is opened, that the path is a regular file (a
folder, a FIFO, a device or a link to one is refused by its kind: a FIFO would block,
``/dev/zero`` never ends), that it is within the size cap of its kind, and (for text) that it
is UTF-8; any failure is one line naming the file, raised as the caller's :class:`UserError`
subclass. Commands add nothing of their own: a new command that reads a file through these
functions inherits every check.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from pnp_twin.twin.errors import UserError, tail

# The size caps of each kind of input: far above any real one, well below what would hurt.
SCENARIO_BYTES = 1_000_000  # a scenario is a page of settings
TRACE_BYTES = 40_000_000  # about two million rows: within a run's budget (twin.budget)
TARGETS_BYTES = 10_000_000  # a targets file is a few measured points
COSTS_BYTES = 1_000_000  # a price table
POLICY_BYTES = 5_000_000  # a policy's Python source
MODEL_BYTES = 500_000_000  # a model's weights

KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(path: str | Path) -> str | None:
    """What ``path`` is when it exists but is not a regular file (after following links):
    "a folder", "a FIFO (named pipe)", "a character device" ...; None for a regular file or a
    path that does not exist. Only ``stat`` is called: a FIFO or a device is never opened."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in KINDS if test(mode)), "not a regular file")


def check_regular(path: str | Path, label: str, error: type[UserError] = UserError) -> None:
    """Refuse an existing ``path`` that is not a regular file, by its kind, before any read."""
    kind = file_kind(path)
    if kind is not None:
        if Path(path).is_symlink():
            kind = f"a link to {kind} ('{tail(os.path.realpath(path), 40)}')"
        raise error(f"{label}: '{tail(str(path))}' is {kind}; give a regular file")


def check_user_file(
    path: str | Path, label: str, max_bytes: int, error: type[UserError] = UserError
) -> Path:
    """``path`` if it is an existing regular file of at most ``max_bytes``; else one line.
    For inputs a library opens itself (a model's weights, a policy's module)."""
    p = Path(path)
    check_regular(p, label, error)
    try:
        size = p.stat().st_size
    except OSError as e:
        raise error(f"{label}: cannot read '{tail(str(p))}': {e.strerror or e}") from None
    if size > max_bytes:
        raise error(
            f"{label}: '{tail(str(p))}' is {size:,} bytes; at most {max_bytes:,} are allowed"
        )
    return p


def read_user_bytes(
    path: str | Path, label: str, max_bytes: int, error: type[UserError] = UserError
) -> bytes:
    """The bytes of ``path``; at most ``max_bytes`` are ever read (a file that grows while
    it is read is refused too)."""
    p = check_user_file(path, label, max_bytes, error)
    try:
        with open(p, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as e:
        raise error(f"{label}: cannot read '{tail(str(p))}': {e.strerror or e}") from None
    if len(data) > max_bytes:
        raise error(
            f"{label}: '{tail(str(p))}' is over {max_bytes:,} bytes; at most {max_bytes:,} "
            "are allowed"
        )
    return data


def read_user_text(
    path: str | Path, label: str, max_bytes: int, error: type[UserError] = UserError
) -> str:
    """The UTF-8 text of ``path`` (a leading BOM dropped), or an ``error`` of one line."""
    data = read_user_bytes(path, label, max_bytes, error)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise error(
            f"{label}: '{tail(str(path))}' is not UTF-8 text (byte 0x{data[e.start]:02x} on "
            f"line {line}); save it as UTF-8"
        ) from None


def folder_files(
    path: str | Path, label: str, suffix: str, error: type[UserError] = UserError
) -> list[Path]:
    """The ``suffix`` files of the folder ``path``, sorted by name (each still read through
    the readers above); a folder that cannot be listed or holds none is refused."""
    p = Path(path)
    try:
        found = sorted(e for e in p.iterdir() if e.suffix.lower() == suffix and not e.is_dir())
    except OSError as e:
        raise error(f"{label}: cannot list '{tail(str(p))}': {e.strerror or e}") from None
    return found
