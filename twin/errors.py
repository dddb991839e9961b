"""The one error family the command line turns into a one-line message and exit code 2.

Also the helpers that keep such messages short: :func:`excerpt` (never echo more than a
few dozen characters of what the user gave), :func:`clip` and :func:`tail`. Every user file
is opened through :mod:`pnp_twin.twin.inputs`.
"""

from __future__ import annotations

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
