"""Training progress on stderr: a bar that fits 80 columns on a terminal, plain lines off one.

On a terminal: one rich progress line (what, a 20-column bar, done/total, elapsed, a short
status such as ``G 71.2% eps 0.02 1050/s``) that stays within 80 columns. Off a terminal (a
log file, CI, a pipe): a plain line at most every :data:`PLAIN_EVERY` seconds, at every
tenth of the run and at its end, e.g. ``train async: step 20000/200000 (10%) G 71.2 %
reward/step 0.084 eps 0.70 1050 steps/s``.
"""

from __future__ import annotations

import time
from types import TracebackType
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from pnp_twin.cli.console import note, stderr_console

PLAIN_EVERY = 30.0  # s between plain lines off a terminal


class TrainProgress:
    """A context manager; feed it :meth:`training_row`, :meth:`rollout_row` or :meth:`advance`."""

    def __init__(self, what: str, total: int, console: Console | None = None) -> None:
        self.what, self.total, self.done = what, total, 0
        console = console or stderr_console()
        self.terminal = console.is_terminal
        self.bar: Progress | None = None
        if self.terminal:
            self.bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(bar_width=20),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TextColumn("{task.fields[info]}"),
                console=console,
            )
            self.task = self.bar.add_task(what[:22], total=total, info="")
        self.printed_at = -float("inf")
        self.tenth = -1

    def __enter__(self) -> TrainProgress:
        if self.bar is not None:
            self.bar.start()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()
            self.bar = None

    def show(self, done: int, short: str, long: str) -> None:
        """Progress ``done`` of ``total``, with a short (bar) and a long (plain line) status."""
        self.done = done
        if self.bar is not None:
            self.bar.update(self.task, completed=done, info=short[:26])
            return
        now, tenth = time.monotonic(), 10 * done // max(self.total, 1)
        if now - self.printed_at >= PLAIN_EVERY or tenth > self.tenth or done >= self.total:
            self.printed_at, self.tenth = now, tenth
            pct = 100 * done // max(self.total, 1)
            note(f"{self.what}: {done}/{self.total} ({pct}%) {long}".rstrip())

    def training_row(self, p: dict[str, Any]) -> None:
        """A row of the td trainer's progress."""
        short = f"G {p['gripping_rate']:.1f}% eps {p['epsilon']:.2f} {p['steps_per_s']:.0f}/s"
        long = (
            f"G {p['gripping_rate']:.1f} %  reward/step {p['reward']:.3f}  "
            f"eps {p['epsilon']:.2f}  loss {p['loss']:.4g}  {p['steps_per_s']:.0f} steps/s"
        )
        self.show(int(p["step"]), short, long)

    def rollout_row(self, row: dict[str, Any]) -> None:
        """A round of the rollout trainer."""
        short = f"G {row['gripping_rate']:.2f}% {row['diff_vs_best_rule']:+.2f}"
        long = (
            f"{row['step']} labels  G {row['gripping_rate']:.2f} %  "
            f"vs {row['best_rule']} {row['diff_vs_best_rule']:+.2f}"
        )
        self.show(int(row["episodes"]), short, long)

    def advance(self, name: str) -> None:
        """One more of ``total`` runs finished."""
        self.show(self.done + 1, name[-26:], f"finished {name}")
