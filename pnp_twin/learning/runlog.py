"""A training run's CSV logs: rows appended as training goes, trimmed before a resume."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

from pnp_twin.twin.output import write_text


def truncate_log(path: Path, step: int) -> None:
    """Drop the rows of a CSV log after ``step`` (atomically), e.g. before a resume."""
    if not path.is_file():
        return
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    keep = rows[:1] + [r for r in rows[1:] if r and int(r[0]) <= step]
    if len(keep) == len(rows):
        return
    text = io.StringIO()
    csv.writer(text).writerows(keep)
    write_text(text.getvalue(), path)


class CsvLog:
    """Rows appended to a CSV file, flushed each time (readable while training)."""

    def __init__(self, path: Path, columns: list[str], append: bool) -> None:
        # a file without its header row (killed before the first flush) starts again
        fresh = not (append and path.is_file() and path.stat().st_size > 0)
        self.file = path.open("w" if fresh else "a", newline="")
        self.writer = csv.writer(self.file)
        if fresh:
            self.writer.writerow(columns)

    def row(self, values: list[Any]) -> None:
        self.writer.writerow([f"{v:.6g}" if isinstance(v, float) else v for v in values])
        self.file.flush()

    def close(self) -> None:
        self.file.close()
