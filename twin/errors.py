"""The one error family the command line turns into a one-line message and exit code 2.

Also the two helpers that keep such messages short and honest about user files:
:func:`excerpt` (never echo more than a few dozen characters of what the user gave) and
:func:`read_user_text` (a file's text, or one line saying why it cannot be read: missing,
too large, not UTF-8).
"""

from __future__ import annotations

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


def excerpt(value: Any, limit: int = EXCERPT) -> str:
    """``repr(value)`` (a float as ``%g``), clipped: how a message quotes a user's value."""
    return clip(f"{value:g}" if isinstance(value, float) else repr(value), limit)


def read_user_text(
    path: Path, label: str, max_bytes: int, error: type[UserError] = UserError
) -> str:
    """The UTF-8 text of ``path`` (a leading BOM dropped), or an ``error`` of one line."""
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise error(f"{label}: '{path}' is {size:,} bytes; at most {max_bytes:,} are allowed")
        data = path.read_bytes()
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
