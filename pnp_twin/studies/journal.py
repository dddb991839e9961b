"""The resume journal of a study folder.

Finished runs are journaled by the coordinating process as results arrive, as JSON lines
appended to segment files ``DIR/runs/NNNNNN.jsonl`` (one segment per session, never
appended to by another): a row that comes after a quiet half second is written and fsynced
at once; rows that come faster are buffered and written together by a timer at most half a
second after the first of them (and always before the tables are built, when the session
closes, on Ctrl-C, and before a fresh start deletes the study it replaced), so an
interrupted study (Ctrl-C, a killed process) loses at most the runs of its last half second.
``DIR/study.json`` holds the study definition: re-running the same command skips finished
runs; a different definition in the same folder is refused (naming the fields that changed)
unless the caller asks for a fresh start. Only the replications may change: earlier runs
are kept and new ones added (their seeds do not depend on the count, so common random numbers
hold). Folders written before segments (one ``DIR/runs/<run_id>.json`` per run) are read as
they are.

While a journal is open it holds the folder's lock (:mod:`pnp_twin.studies.lock`), so a
second process cannot write into the same folder. A fresh start moves the old study aside
into ``DIR/.replaced/`` and deletes it only once the new study has journaled its first
run; if the new one fails before that, the old study is put back.

Damaged lines: a line that is not readable JSON (a write cut short by a kill leaves a last
line without its newline) is dropped from its segment and the run done again (a warning is
logged); a readable row whose values are impossible (an edited line: G = 1234.5, a negative
count, another run's seed) is refused with one line naming the file, the line and the field.
A ``study.json`` that cannot be read is refused with one line.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import shutil
import threading
import time
from collections.abc import Iterable, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

from pnp_twin.studies.execute import cell
from pnp_twin.studies.lock import StudyLock
from pnp_twin.studies.plan import RunSpec, StudyError
from pnp_twin.twin.output import atomic_path, dumps_json, remove_temporaries, write_json

log = logging.getLogger(__name__)

DEFINITION = "study.json"
REPLACED = ".replaced"
OUTPUTS = (
    "runs",
    "records",
    DEFINITION,
    "meta.json",
    "results.parquet",
    "results.csv",
    "summary.csv",
    "paired.csv",
    "best.csv",
    "sizing.json",
    "mix.json",
    "report.html",
)
REPLICATION_KEYS = ("replications", "precision")  # may change: runs are added or reused
# analysis settings (how the runs are read, not what is simulated): may change freely, every
# stored run is reused; "target" and "confidence" at the top are how older folders kept them
ANALYSIS_KEYS = ("analysis", "target", "confidence")
COUNTS = re.compile(r"parts_\w+|r\d+_(picks|passed_on|lost|missed)|rule_\w+")
NUMBERS = re.compile(
    r"gripping_rate|throughput|part_flow|max_throughput|efficiency|utilisation|wall_time"
    r"|cycle_time_\w+|r\d+_\w+"
)
TEXT_FIELDS = ("scenario", "termination")
SEGMENT = re.compile(r"\d{6}\.jsonl")  # runs/000001.jsonl, one per session
FLUSH_SECONDS = 0.5  # a batch of rows is written and fsynced at most this long after its first
FLUSH_ROWS = 1000  # ... or once it holds this many rows


def _show(value: Any, width: int = 40) -> str:
    text = json.dumps(value, default=str)
    return text if len(text) <= width else text[: width - 3] + "..."


def differences(old: Any, new: Any, path: str = "") -> list[tuple[str, Any, Any]]:
    """The (dotted path, old value, new value) of every leaf that differs."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for key in sorted(set(old) | set(new), key=str):
            sub = f"{path}.{key}" if path else str(key)
            out += differences(old.get(key), new.get(key), sub)
        return out
    return [] if old == new else [(path or "definition", old, new)]


def changed_text(changes: list[tuple[str, Any, Any]], limit: int = 3) -> str:
    """``feeder.rate was 10.0, now 12.0; ...`` for the first ``limit`` changes."""
    parts = [f"{p} was {_show(a)}, now {_show(b)}" for p, a, b in changes[:limit]]
    more = f"; and {len(changes) - limit} more" if len(changes) > limit else ""
    return "; ".join(parts) + more


def row_problem(row: Any, spec: RunSpec) -> str | None:
    """Why ``row`` cannot be the journaled result of ``spec`` (None if it can)."""
    if not isinstance(row, dict):
        return f"holds {type(row).__name__}, not a run's row"
    expected = {
        "run_id": spec.run_id,
        "point": spec.point,
        "policy": spec.policy,
        "replication": spec.replication,
        "seed": spec.seed,
        **{p: cell(v) for p, v in spec.values.items()},
    }
    for key, want in expected.items():
        if key not in row:
            return f"has no '{key}'"
        if row[key] != want or type(row[key]) is bool:
            return f"{key} = {_show(row[key])} is not this run's; expected {_show(want)}"
    if "gripping_rate" not in row:
        return "has no 'gripping_rate'"
    for key, value in row.items():
        if key in expected or key in TEXT_FIELDS:
            continue
        problem = _value_problem(key, value)
        if problem:
            return f"{key} = {_show(value)} is not allowed; {problem}"
    picked, presented = row.get("parts_picked"), row.get("parts_presented")
    if isinstance(picked, int) and isinstance(presented, int) and picked > presented:
        return f"parts_picked = {picked} is more than parts_presented = {presented}"
    return None


@lru_cache(maxsize=4096)
def _kind(key: str) -> tuple[bool, bool]:
    """(is a count, is a number column) of a row key."""
    count = COUNTS.fullmatch(key) is not None
    return count, count or NUMBERS.fullmatch(key) is not None


def _value_problem(key: str, value: Any) -> str | None:
    count, number = _kind(key)
    if isinstance(value, str) and not number:
        return None  # a text column (a label some KPI carries)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        return "a number is expected"
    if math.isnan(value):
        return None if not count else "a whole number >= 0 is expected"
    if count:
        return None if isinstance(value, int) and value >= 0 else "a whole number >= 0"
    if key == "gripping_rate" and not 0 <= value <= 100:
        return "a percentage in [0, 100] is expected"
    if value < 0:
        return "a number >= 0 is expected"
    return None


class Journal:
    """The runs finished so far in one study folder; holds the folder's lock while open."""

    def __init__(
        self, folder: Path, definition: dict[str, Any], fresh: bool = False, command: str = ""
    ) -> None:
        self.folder = Path(folder)
        self.runs = self.folder / "runs"
        self.replaced = self.folder / REPLACED
        self._found: dict[str, tuple[Any, str]] | None = None  # run_id -> (row, where)
        self._pending: list[str] = []  # JSON lines recorded, not yet written
        self._flushed_at = -math.inf  # monotonic time of the last write
        self._guard = threading.RLock()  # the timer's flush and record() share the buffer
        self._timer: threading.Timer | None = None  # writes a batch FLUSH_SECONDS after it starts
        self._segment: Path | None = None  # this session's segment, once it has one
        self._lines = 0  # lines written to it
        self.lock = StudyLock(self.folder)
        self.lock.acquire(command)
        try:
            self._open(json.loads(dumps_json(definition)), fresh)
        except BaseException:
            self.close()
            raise

    def _open(self, definition: dict[str, Any], fresh: bool) -> None:
        self._settle_replaced()
        stored = self.folder / DEFINITION
        if fresh:
            self._move_aside()
        elif stored.is_file():
            self._compare(self._read_definition(stored), definition)
        elif self._has_runs():
            raise StudyError(
                f"--out {self.folder}: has runs/ but no {DEFINITION}; add --fresh to start over"
            )
        self.runs.mkdir(parents=True, exist_ok=True)
        write_json(definition, stored)
        for where in (self.folder, self.runs, self.folder / "records"):
            for tmp in remove_temporaries(where):  # left by a write that was killed mid-way
                log.info("removed %s, left by an interrupted write", tmp)

    def _read_definition(self, stored: Path) -> dict[str, Any]:
        try:
            old = json.loads(stored.read_text(encoding="utf-8"))
        except (ValueError, UnicodeDecodeError) as e:
            why = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise StudyError(
                f"{stored}: is damaged ({why}); add --fresh to start the study over"
            ) from None
        if not isinstance(old, dict):
            raise StudyError(f"{stored}: is damaged (not an object); add --fresh to start over")
        return old

    def _compare(self, old: dict[str, Any], new: dict[str, Any]) -> None:
        def without(d: dict[str, Any]) -> dict[str, Any]:
            out = {k: v for k, v in d.items() if k not in REPLICATION_KEYS + ANALYSIS_KEYS}
            if isinstance(out.get("scenario"), dict):  # its sweep section is the rest of d
                out["scenario"] = {k: v for k, v in out["scenario"].items() if k != "sweep"}
            return out

        changes = differences(without(old), without(new))
        if changes:
            raise StudyError(
                f"--out {self.folder}: holds a different study ({changed_text(changes)}); "
                f"add --fresh to start it over or choose another folder"
            )
        for key in REPLICATION_KEYS + ANALYSIS_KEYS:
            if old.get(key) != new.get(key):
                log.info(
                    "%s: %s was %s, now %s; earlier runs are kept",
                    self.folder,
                    key,
                    _show(old.get(key)),
                    _show(new.get(key)),
                )

    def _move_aside(self) -> None:
        """Move the old study's outputs into .replaced/ (deleted once the new one runs)."""
        shutil.rmtree(self.replaced, ignore_errors=True)
        present = [n for n in OUTPUTS if (self.folder / n).exists()]
        if not present:
            return
        self.replaced.mkdir()
        for name in present:
            (self.folder / name).rename(self.replaced / name)
        log.info("moved the old study in %s aside", self.folder)

    def _settle_replaced(self) -> None:
        """A --fresh start that was killed: keep the new study if it ran, else the old."""
        if not self.replaced.is_dir():
            return
        if self._has_runs():
            self.started()
        else:
            self.restore()

    def started(self) -> None:
        """The new study has journaled a run: delete the study a fresh start moved aside
        (once the run is on disk)."""
        if self.replaced.is_dir():
            self.flush()
            shutil.rmtree(self.replaced, ignore_errors=True)
            log.info("deleted the old study of %s", self.folder)

    def restore(self) -> None:
        """Put back the study a fresh start moved aside (the new one never ran)."""
        if not self.replaced.is_dir():
            return
        for name in OUTPUTS:
            p = self.folder / name
            if (self.replaced / name).exists():
                if p.is_dir():
                    shutil.rmtree(p)
                elif p.exists():
                    p.unlink()
                (self.replaced / name).rename(p)
        shutil.rmtree(self.replaced, ignore_errors=True)
        self._found, self._segment, self._lines = None, None, 0  # read the old runs anew
        log.info("restored the earlier study of %s", self.folder)

    def close(self) -> None:
        """Write the rows still buffered and release the folder's lock."""
        try:
            if self._timer is not None:
                self._timer.cancel()
            self.flush()
        finally:
            self.lock.release()

    # -- the runs' rows: JSON lines in segments -------------------------------------------
    def _has_runs(self) -> bool:
        """Whether runs/ holds any journaled run: a segment with a complete, readable row
        (a line cut short by a kill is no run; it is dropped when read), or an older
        folder's run file."""
        if not self.runs.is_dir():
            return False
        return any(_legacy(p) for p in self.runs.iterdir()) or bool(journaled(self.runs))

    def _segments(self) -> list[Path]:
        if not self.runs.is_dir():
            return []
        return sorted(p for p in self.runs.iterdir() if SEGMENT.fullmatch(p.name))

    def _read(self) -> dict[str, tuple[Any, str]]:
        """Every journaled row by run id (read from disk once, then kept up to date)."""
        if self._found is not None:
            return self._found
        found: dict[str, tuple[Any, str]] = {}
        if self.runs.is_dir():
            for path in sorted(p for p in self.runs.iterdir() if _legacy(p)):
                row = self._read_legacy(path)
                if row is not None:
                    found[path.stem] = (row, str(path))
        for path in self._segments():
            for key, row, where in self._read_segment(path):
                found[key] = (row, where)
        self._found = found
        return found

    def _read_legacy(self, path: Path) -> Any:
        """A run file of a folder written before segments; None if damaged (deleted)."""
        try:
            return json.loads(path.read_text(encoding="utf-8"))
        except (ValueError, UnicodeDecodeError) as e:
            why = str(e).splitlines()[0] if str(e) else type(e).__name__
            log.warning("%s: is damaged (%s); running it again", path, why)
            path.unlink(missing_ok=True)
            return None

    def _read_segment(self, path: Path) -> list[tuple[str, Any, str]]:
        """(run id, row, "FILE line N") of each line of a segment. Lines that are not
        readable JSON (a write cut short) are dropped from the file, their runs redone; a
        readable line that is not a run's row is refused."""
        data = path.read_bytes()
        lines = data.split(b"\n")
        out, kept, damaged = [], [], 0
        for n, raw in enumerate(lines, start=1):
            if not raw.strip():
                continue
            where = f"{path} line {n}"
            try:
                if n == len(lines):  # no newline after it: its write was cut short
                    raise ValueError("the line was cut short")
                row = json.loads(raw.decode("utf-8"))
            except (ValueError, UnicodeDecodeError) as e:
                why = str(e).splitlines()[0] if str(e) else type(e).__name__
                log.warning("%s: is damaged (%s); running it again", where, why)
                damaged += 1
                continue
            kept.append(raw)
            if not isinstance(row, dict) or not isinstance(row.get("run_id"), str):
                what = "a row without a run_id" if isinstance(row, dict) else type(row).__name__
                raise StudyError(
                    f"{where}: holds {what}, not a run's row; delete that line to run it again"
                )
            out.append((row["run_id"], row, where))
        if damaged:  # the file without its damaged lines (atomically: a kill keeps either)
            text = b"".join(line + b"\n" for line in kept)
            with atomic_path(path) as tmp:
                tmp.write_bytes(text)
            if kept:  # the line numbers now count the kept lines
                return self._read_segment(path)
        return out

    def flush(self) -> None:
        """Append the buffered rows to this session's segment and fsync it."""
        with self._guard:
            self._timer = None
            if self._pending:
                self._write_pending()
            self._flushed_at = time.monotonic()

    def _write_pending(self) -> None:
        segment = self._session_segment()
        created = not segment.exists()
        text = "".join(self._pending).encode("utf-8")
        fd = os.open(segment, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
        try:
            os.write(fd, text)
            os.fsync(fd)
        finally:
            os.close(fd)
        if created:
            _fsync_dir(self.runs)  # the segment's name is on disk too
        self._lines += len(self._pending)
        self._pending.clear()

    def _session_segment(self) -> Path:
        """This session's segment: the next number after those in runs/."""
        if self._segment is None:
            numbers = [int(p.name[:6]) for p in self._segments()]
            self._segment = self.runs / f"{max(numbers, default=0) + 1:06d}.jsonl"
        return self._segment

    def done(self) -> set[str]:
        """Ids of the journaled runs (not yet checked)."""
        return set(self._read())

    def record(self, row: Mapping[str, Any]) -> None:
        """Journal one finished run (NaN kept so the row reads back exactly); written with
        its batch (see the module docstring)."""
        line = _dumps_row(row)
        found = self._read()
        with self._guard:
            self._pending.append(line)
            where = f"{self._session_segment()} line {self._lines + len(self._pending)}"
            found[str(row["run_id"])] = (json.loads(line), where)
            quiet = time.monotonic() - self._flushed_at >= FLUSH_SECONDS
            if quiet or len(self._pending) >= FLUSH_ROWS:
                if self._timer is not None:
                    self._timer.cancel()
                self.flush()
            elif self._timer is None:
                self._timer = threading.Timer(FLUSH_SECONDS, self.flush)
                self._timer.daemon = True
                self._timer.start()

    def load(self, spec: RunSpec) -> dict[str, Any] | None:
        """``spec``'s journaled row, checked; None if not run yet (or its line was damaged)."""
        entry = self._read().get(spec.run_id)
        if entry is None:
            return None
        row, where = entry
        problem = row_problem(row, spec)
        if problem:
            what = "that line" if " line " in where else "the file"
            raise StudyError(
                f"{where} (run {spec.run_id}): {problem}; delete {what} to run it again"
            )
        return dict(row)

    def rows(self, specs: Iterable[RunSpec]) -> list[dict[str, Any] | None]:
        """The checked row of each spec (None where not run yet); buffered rows are written
        first."""
        self.flush()
        return [self.load(s) for s in specs]


def _legacy(path: Path) -> bool:
    """A run file of a folder journaled before segments (``runs/<run_id>.json``)."""
    return path.suffix == ".json" and not path.name.startswith(".")


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems cannot fsync a folder; the data itself is synced
    finally:
        os.close(fd)


def _dumps_row(row: Mapping[str, Any]) -> str:
    """One JSON line (NaN as ``NaN``); plain rows skip the numpy / pandas conversion."""
    try:
        text = json.dumps(row, allow_nan=True, separators=(",", ":"))
    except TypeError:
        text = dumps_json(row, keep_nan=True)
    return text + "\n"


def journaled(runs: Path) -> set[str]:
    """Run ids journaled in a ``runs/`` folder (complete lines of its segments, and an older
    folder's run files), without checking or changing anything: for watching a study."""
    ids: set[str] = set()
    if not runs.is_dir():
        return ids
    for path in runs.iterdir():
        if _legacy(path):
            ids.add(path.stem)
        elif SEGMENT.fullmatch(path.name):
            for raw in path.read_bytes().split(b"\n")[:-1]:
                try:
                    row = json.loads(raw.decode("utf-8"))
                except (ValueError, UnicodeDecodeError):
                    continue
                if isinstance(row, dict) and isinstance(row.get("run_id"), str):
                    ids.add(row["run_id"])
    return ids
