"""Study folders journaled by earlier versions, read once to migrate them into the store.

Two layouts came before ``runs/runs.sqlite``: one ``runs/<run_id>.json`` file per run, then
JSON lines appended to segment files ``runs/NNNNNN.jsonl`` (one per session; a later line of
a run wins). :func:`read_legacy_runs` reads both as :class:`pnp_twin.studies.journal.Journal`
migrates them: a file or line that is not readable JSON (a write cut short by a kill, an
empty file) is left out with a warning and its run done again; a readable one that is not a
run's row is refused with one line naming the file (and the line). After the import each
file is renamed ``<name>.migrated``, so it is read once.
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path
from typing import Any

from pnp_twin.studies.plan import StudyError

log = logging.getLogger(__name__)

SEGMENT = re.compile(r"\d{6}\.jsonl")  # runs/000001.jsonl, one per session
MIGRATED = ".migrated"


def is_run_file(path: Path) -> bool:
    """A run file of a folder journaled before segments (``runs/<run_id>.json``)."""
    return path.suffix == ".json" and not path.name.startswith(".")


def legacy_files(runs: Path) -> list[Path]:
    """The run files, then the segments (in order), of an earlier version's ``runs/``."""
    if not runs.is_dir():
        return []
    entries = list(runs.iterdir())
    files = sorted(p for p in entries if is_run_file(p))
    return files + sorted(p for p in entries if SEGMENT.fullmatch(p.name))


def read_legacy_runs(runs: Path) -> dict[str, dict[str, Any]]:
    """Every readable run of the earlier layouts in ``runs`` by run id (later lines win)."""
    found: dict[str, dict[str, Any]] = {}
    for path in legacy_files(runs):
        if is_run_file(path):
            row = _read_run_file(path)
            if row is not None:
                found[path.stem] = row
        else:
            found.update(_read_segment(path))
    return found


def _why(e: Exception) -> str:
    return str(e).splitlines()[0] if str(e) else type(e).__name__


def _read_run_file(path: Path) -> dict[str, Any] | None:
    try:
        row = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as e:
        log.warning("%s: is damaged (%s); running it again", path, _why(e))
        return None
    if not isinstance(row, dict):
        raise StudyError(
            f"{path}: holds {type(row).__name__}, not a run's row; delete the file to run it again"
        )
    return row


def _read_segment(path: Path) -> dict[str, dict[str, Any]]:
    lines = path.read_bytes().split(b"\n")
    found: dict[str, dict[str, Any]] = {}
    for n, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        where = f"{path} line {n}"
        try:
            if n == len(lines):  # no newline after it: its write was cut short
                raise ValueError("the line was cut short")
            row = json.loads(raw.decode("utf-8"))
        except (ValueError, UnicodeDecodeError) as e:
            log.warning("%s: is damaged (%s); running it again", where, _why(e))
            continue
        if not isinstance(row, dict) or not isinstance(row.get("run_id"), str):
            what = "a row without a run_id" if isinstance(row, dict) else type(row).__name__
            raise StudyError(
                f"{where}: holds {what}, not a run's row; delete that line to run it again"
            )
        found[row["run_id"]] = row
    return found


def legacy_ids(runs: Path) -> set[str]:
    """Run ids of the earlier layouts in ``runs`` (complete, readable rows), read-only."""
    ids: set[str] = set()
    for path in legacy_files(runs):
        if is_run_file(path):
            ids.add(path.stem)
            continue
        for raw in path.read_bytes().split(b"\n")[:-1]:
            try:
                row = json.loads(raw.decode("utf-8"))
            except (ValueError, UnicodeDecodeError):
                continue
            if isinstance(row, dict) and isinstance(row.get("run_id"), str):
                ids.add(row["run_id"])
    return ids


def mark_migrated(paths: list[Path]) -> None:
    """Rename each imported file ``<name>.migrated`` (kept for the user to delete)."""
    for path in paths:
        path.replace(path.with_name(path.name + MIGRATED))
