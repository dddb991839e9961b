"""The one error family the command line turns into a one-line message and exit code 2.

Also the two helpers that keep such messages short and honest about user files:
:func:`excerpt` (never echo more than a few dozen characters of what the user gave) and
:func:`read_user_text` (a file's text, or one line saying why it cannot be read: missing,
too large, not UTF-8).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

EXCERPT = 60  # characters of user input a message may quote


class UserError(ValueError):
    """A user mistake (bad file, bad value, unknown name); ``str(e)`` is one clear line."""


class ScenarioError(UserError):
    """A user mistake in a scenario, an override or a file it names; one line for the CLI."""


def clip(text: str, limit: int = EXCERPT) -> str:
    """``text`` on one line, cut to ``limit`` characters (saying how much was left out)."""
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def tail(path: str, limit: int = 2 * EXCERPT) -> str:
    """A path on one line, its start cut when longer than ``limit`` (the name is kept)."""
    text = " ".join(str(path).split())
    return text if len(text) <= limit else f"...{text[-(limit - 3) :]}"


def excerpt(value: Any, limit: int = EXCERPT) -> str:
    """``repr(value)`` (a float as ``%g``), clipped: how a message quotes a user's value."""
    return clip(f"{value:g}" if isinstance(value, float) else repr(value), limit)


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
    """Refuse an existing ``path`` that is not a regular file, by its kind, before any read
    (a FIFO would block, ``/dev/zero`` never ends)."""
    kind = file_kind(path)
    if kind is not None:
        if Path(path).is_symlink():
            kind = f"a link to {kind} ('{tail(os.path.realpath(path), 40)}')"
        raise error(f"{label}: '{tail(str(path))}' is {kind}; give a regular file")


def read_user_text(
    path: Path, label: str, max_bytes: int, error: type[UserError] = UserError
) -> str:
    """The UTF-8 text of ``path`` (a leading BOM dropped), or an ``error`` of one line.

    A path that is not a regular file (a folder, a FIFO, a device, a link to one) is refused
    by its kind before it is opened; at most ``max_bytes`` are ever read.
    """
    check_regular(path, label, error)
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise error(f"{label}: '{path}' is {size:,} bytes; at most {max_bytes:,} are allowed")
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise error(f"{label}: '{path}' is over {max_bytes:,} bytes; at most that are allowed")
    except OSError as e:
        raise error(f"{label}: cannot read '{path}': {e.strerror or e}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise error(
            f"{label}: '{path}' is not UTF-8 text (byte 0x{data[e.start]:02x} on line {line}); "
            "save it as UTF-8"
        ) from None
