"""The per-run journal of an evaluated point (``calibrate``, ``design``, ``capacity``).

Each run is appended to ``DIR/evals/runs.jsonl`` the moment it finishes, as one JSON line
(``{"key": ..., "row": {KPI: value}}``) written and fsynced at once, so a killed study
loses no finished run: asking again replays every run of the log and simulates only the
others, even those of a point that was cut short half-way. The key hashes exactly what was
simulated (the run's resolved scenario, its policy and seed, the KPIs kept).

A line cut short by a kill (the bytes after the last newline) is cut off the file before
the next line is appended, and its run done again; a complete line that is not readable is
skipped with a warning (its run is done again). The command that writes the log holds the
folder's lock, so no two processes append to it at once.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

RUNS_FILE = "runs.jsonl"


class RunLog:
    """The runs journalled in ``folder`` by key; :meth:`add` appends one as it finishes."""

    def __init__(self, folder: Path) -> None:
        self.path = Path(folder) / RUNS_FILE
        self.rows: dict[str, dict[str, float]] = self._read()

    def _read(self) -> dict[str, dict[str, float]]:
        if not self.path.is_file():
            return {}
        data = self.path.read_bytes()
        lines = data.split(b"\n")
        torn = lines.pop()  # the bytes after the last newline: a write cut short
        if torn:
            log.warning("%s: the last line was cut short; running its run again", self.path)
            os.truncate(self.path, len(data) - len(torn))
        rows: dict[str, dict[str, float]] = {}
        for n, raw in enumerate(lines, start=1):
            entry = _parse(raw)
            if entry is None:
                if raw.strip():
                    log.warning("%s line %d: is damaged; running its run again", self.path, n)
                continue
            rows[entry[0]] = entry[1]
        return rows

    def get(self, key: str) -> dict[str, float] | None:
        return self.rows.get(key)

    def add(self, key: str, row: Mapping[str, float]) -> None:
        """Append one finished run and fsync it before returning."""
        line = json.dumps({"key": key, "row": dict(row)}, allow_nan=True) + "\n"
        fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
        try:
            os.write(fd, line.encode("utf-8"))
            os.fsync(fd)
        finally:
            os.close(fd)
        self.rows[key] = dict(row)


def _parse(raw: bytes) -> tuple[str, dict[str, float]] | None:
    """(key, row) of one line; None if it is not a run's line."""
    try:
        entry = json.loads(raw.decode("utf-8"))
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(entry, dict) or not isinstance(entry.get("key"), str):
        return None
    row = entry.get("row")
    if not isinstance(row, dict) or not all(_number(v) for v in row.values()):
        return None
    return entry["key"], {str(k): float(v) for k, v in row.items()}


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def journalled(folder: Path) -> int:
    """How many runs ``folder``'s log holds (complete lines), without changing it: for
    watching a study."""
    path = Path(folder) / RUNS_FILE
    if not path.is_file():
        return 0
    return sum(1 for raw in path.read_bytes().split(b"\n")[:-1] if _parse(raw) is not None)
