"""Where the command line writes: rich consoles for stdout (tables) and stderr (notes).

Tables and JSON go to stdout; progress bars, notes and errors go to stderr, so a piped
stdout holds only results. Off a terminal (piped to a file) stdout is at least 120
columns wide, so tables are not wrapped to a default 80.
"""

from __future__ import annotations

import typer
from rich.console import Console

PIPED_WIDTH = 120


def stdout_console() -> Console:
    """The console for tables on stdout."""
    console = Console(highlight=False)
    if not console.is_terminal:  # piped to a file: no terminal width to respect
        console.width = max(console.width, PIPED_WIDTH)
    return console


def stderr_console() -> Console:
    """The console for progress and notes on stderr."""
    return Console(stderr=True, highlight=False)


def note(message: str) -> None:
    """A line of information on stderr (never mixed into the tables or JSON on stdout)."""
    typer.echo(message, err=True)
