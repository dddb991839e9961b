"""The runs store of a study folder: every finished run, one SQLite row each.

``DIR/evals/runs.sqlite`` (the standard library's ``sqlite3``, WAL journal mode,
``synchronous=FULL``) holds one row per run, keyed by a hash of exactly what was simulated
(the run's resolved scenario, its policy and seed, the KPIs kept). Each run is committed on
its own the moment it finishes, so a killed study loses no finished run: asking again reads
every stored run back by its key (one indexed look-up) and simulates only the others.

The table, readable with any SQLite client (schema version in ``PRAGMA user_version``)::

    CREATE TABLE runs (
        key         TEXT PRIMARY KEY,  -- the run's configuration + policy + seed hash
        label       TEXT,              -- the configuration in words, e.g. "robots.count=3, SD"
        point       TEXT,              -- JSON object: the configuration's varied values
        policy      TEXT,              -- the policy (rule, mix or spec) that ran
        seed        INTEGER,           -- the run's seed
        kpis        TEXT NOT NULL,     -- JSON object: KPI name -> value (strict JSON)
        special     TEXT,              -- JSON object: the KPIs stored as null that are NaN or
                                       -- infinite, e.g. {"cycle_time_mean": "NaN"}
        finished_at TEXT               -- ISO 8601 UTC
    )

A NaN or infinite KPI is ``null`` in ``kpis`` (so SQLite's ``json_extract`` reads every row,
and ``avg`` skips it) and named in ``special``, so the row reads back exactly: NaN as NaN, a
``None`` as ``None``.

A folder journalled by an earlier version (``evals/runs.jsonl``, one JSON line per run) is
migrated when the store is first opened: its rows are imported in one transaction, then the
file is renamed ``runs.jsonl.migrated`` (a kill between the two imports them again, which
changes nothing). Those rows have only ``key`` and ``kpis``: the old log kept nothing else.

A store that is not an SQLite database, or has no readable ``runs`` table, or was written by
a newer version is refused with one line (:class:`StudyError`). A row whose ``kpis`` cannot
be read is treated as absent (a warning is logged) and its run done again. The command that
writes the store holds the folder's lock, so one process writes at a time; others may read.
Opening the store also removes the temporaries (``.*.tmp``) that a killed atomic write of a
point's file left in the folder, once per study rather than once per batch.
"""

from __future__ import annotations

import json
import logging
import math
import sqlite3
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pnp_twin.studies.plan import StudyError

log = logging.getLogger(__name__)

STORE_FILE = "runs.sqlite"
LEGACY_FILE = "runs.jsonl"  # the per-run log of earlier versions, migrated on first open
MIGRATED_SUFFIX = ".migrated"
SCHEMA_VERSION = 1
SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    key TEXT PRIMARY KEY,
    label TEXT,
    point TEXT,
    policy TEXT,
    seed INTEGER,
    kpis TEXT NOT NULL,
    special TEXT,
    finished_at TEXT
)
"""
COLUMNS = ("key", "label", "point", "policy", "seed", "kpis", "special", "finished_at")
NON_FINITE = {"Infinity": math.inf, "-Infinity": -math.inf, "NaN": math.nan}

Row = dict[str, Any]  # KPI name -> value (a float, or a text a KPI carries)


class RunStore:
    """The runs stored in ``folder`` (``DIR/evals``) by key; :meth:`add` commits one."""

    def __init__(self, folder: Path, name: str = STORE_FILE, sync_every: float = 0.0) -> None:
        """``sync_every`` 0: each commit fsynced before it returns (``synchronous=FULL``);
        above 0: commits are in the OS's hands at once (``NORMAL``: a killed process loses
        none) and fsynced with the first commit at least that many seconds after the last
        fsync (a power cut loses at most the runs of that span), for studies whose runs take
        milliseconds."""
        self.folder = Path(folder)
        self.path = self.folder / name
        self.sync_every = sync_every
        self._synced_at = -math.inf  # monotonic time of the last fsynced commit
        self.folder.mkdir(parents=True, exist_ok=True)
        for tmp in self.folder.glob(".*.tmp"):  # a point's file whose write was killed mid-way
            tmp.unlink(missing_ok=True)
        self._db = _connect(self.path)
        try:
            self._prepare()
            self._migrate()
        except BaseException:
            self._db.close()
            raise

    def _prepare(self) -> None:
        with _refusing_damage(self.path):
            version = self._db.execute("PRAGMA user_version").fetchone()[0]
            if version > SCHEMA_VERSION:
                raise StudyError(
                    f"{self.path}: was written by a newer pnp-twin (store version {version}; "
                    f"this one reads up to {SCHEMA_VERSION}); upgrade pnp-twin or choose "
                    "another folder"
                )
            self._db.execute("PRAGMA journal_mode=WAL")
            self._synchronous("FULL" if self.sync_every <= 0 else "NORMAL")
            with self._db:
                self._db.execute(SCHEMA)
                self._db.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            names = [r[1] for r in self._db.execute("PRAGMA table_info(runs)")]
            if not set(COLUMNS) <= set(names):
                missing = next(c for c in COLUMNS if c not in names)
                raise StudyError(
                    f"{self.path}: is damaged (its runs table has no column {missing}); move "
                    "it away to run its runs again"
                )

    def _migrate(self) -> None:
        """Import an earlier version's ``runs.jsonl`` once, then rename it."""
        legacy = self.folder / LEGACY_FILE
        if not legacy.is_file():
            return
        rows = list(read_legacy(legacy))
        with _refusing_damage(self.path), self._db:
            self._db.executemany(
                "INSERT OR IGNORE INTO runs (key, kpis, special) VALUES (?, ?, ?)",
                [(key, *_dumps(row)) for key, row in rows],
            )
        legacy.replace(legacy.with_name(LEGACY_FILE + MIGRATED_SUFFIX))
        log.info("%s: migrated %d runs into %s", legacy, len(rows), self.path)

    def get(self, key: str) -> Row | None:
        """The stored run's KPIs; None when absent (or its row is damaged)."""
        with _refusing_damage(self.path):
            found = self._db.execute(
                "SELECT kpis, special FROM runs WHERE key = ?", (key,)
            ).fetchone()
        if found is None:
            return None
        row = _loads(*found)
        if row is None:
            log.warning("%s: the run %s is damaged; running it again", self.path, key)
        return row

    def add(
        self,
        key: str,
        row: Mapping[str, Any],
        *,
        label: str | None = None,
        point: Mapping[str, Any] | None = None,
        policy: str | None = None,
        seed: int | None = None,
    ) -> None:
        """Store one finished run, committed before this returns."""
        about = {"label": label, "point": point, "policy": policy, "seed": seed}
        self.add_many([(key, row, about)])

    def add_many(self, runs: Sequence[tuple[str, Mapping[str, Any], Mapping[str, Any]]]) -> None:
        """Store (key, KPIs, {label, point, policy, seed}) of each run in one transaction."""
        now = datetime.now(UTC).isoformat(timespec="seconds")
        values = [
            (
                key,
                about.get("label"),
                None if about.get("point") is None else _point(about["point"]),
                about.get("policy"),
                _integer(about.get("seed")),
                *_dumps(row),
                now,
            )
            for key, row, about in runs
        ]
        marks = ", ".join("?" * len(COLUMNS))
        synced = self.sync_every > 0 and time.monotonic() - self._synced_at >= self.sync_every
        if synced:
            self._synchronous("FULL")  # this commit is fsynced
        with _refusing_damage(self.path), self._db:
            self._db.executemany(
                f"INSERT OR REPLACE INTO runs ({', '.join(COLUMNS)}) VALUES ({marks})", values
            )
        if synced:
            self._synchronous("NORMAL")
            self._synced_at = time.monotonic()

    def _synchronous(self, level: str) -> None:
        with _refusing_damage(self.path):
            self._db.execute(f"PRAGMA synchronous={level}")

    def items(self) -> Iterator[tuple[str, Row | None]]:
        """(key, KPIs) of every stored run in the order stored (None: a damaged row)."""
        with _refusing_damage(self.path):
            found = self._db.execute("SELECT key, kpis, special FROM runs ORDER BY rowid")
            for key, kpis, special in found.fetchall():
                yield str(key), _loads(kpis, special)

    def __len__(self) -> int:
        with _refusing_damage(self.path):
            return int(self._db.execute("SELECT count(*) FROM runs").fetchone()[0])

    def close(self) -> None:
        self._db.close()


@contextmanager
def open_store(folder: Path) -> Iterator[RunStore]:
    """The store of ``folder``, closed after the block; a block that fails before storing
    any run leaves no store behind (a refusal writes nothing)."""
    store = RunStore(folder)
    try:
        yield store
    except BaseException:
        empty = len(store) == 0
        store.close()
        if empty:
            for suffix in ("", "-wal", "-shm"):
                (store.path.parent / (STORE_FILE + suffix)).unlink(missing_ok=True)
        raise
    store.close()


def _connect(path: Path) -> sqlite3.Connection:
    try:
        # autocommit off at the driver: transactions are the explicit `with db:` blocks
        return sqlite3.connect(path, timeout=30.0)
    except sqlite3.Error as e:
        raise StudyError(f"{path}: cannot be opened ({e}); check the folder") from None


class _refusing_damage:
    """Turn an SQLite error into one line naming the store (exit 2, not a traceback)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind: Any, error: Any, _tb: Any) -> None:
        if isinstance(error, sqlite3.DatabaseError):
            why = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise StudyError(
                f"{self.path}: is damaged or unreadable ({why}); move it away to run its runs again"
            ) from None


def _integer(value: Any) -> int | None:
    """A seed as SQLite's INTEGER holds it (64 bits); None when it does not fit."""
    if isinstance(value, int) and not isinstance(value, bool) and -(2**63) <= value < 2**63:
        return value
    return None


def _point(values: Mapping[str, Any]) -> str:
    return json.dumps({str(k): _finite(v) for k, v in values.items()}, default=str, sort_keys=True)


def _finite(value: Any) -> Any:
    return None if isinstance(value, float) and not math.isfinite(value) else value


def _dumps(row: Mapping[str, Any]) -> tuple[str, str | None]:
    """``kpis`` and ``special`` of a row: strict JSON (SQLite's json functions read it),
    each NaN or infinity null in the first and named in the second."""
    special = {
        str(k): "NaN" if math.isnan(v) else ("Infinity" if v > 0 else "-Infinity")
        for k, v in row.items()
        if isinstance(v, float) and not math.isfinite(v)
    }
    kpis = json.dumps({str(k): _finite(v) for k, v in row.items()}, allow_nan=False)
    return kpis, json.dumps(special) if special else None


def _loads(text: Any, special: Any = None) -> Row | None:
    """A stored ``kpis`` object with its ``special`` values; None when it is not one."""
    try:
        data = json.loads(text)
        extra = json.loads(special) if special is not None else {}
    except (TypeError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(extra, dict):
        return None
    if not all(isinstance(v, str) and v in NON_FINITE for v in extra.values()):
        return None
    for k, v in extra.items():
        if data.get(k, 0) is not None:
            return None  # a special value names a KPI that is not stored as null
        data[k] = NON_FINITE[v]
    return {str(k): v for k, v in data.items()}


def read_legacy(path: Path) -> Iterator[tuple[str, dict[str, float]]]:
    """(key, row) of each complete, readable line of an earlier version's ``runs.jsonl``; a
    line cut short by a kill (after the last newline) or damaged is left out, with a warning."""
    lines = path.read_bytes().split(b"\n")
    if lines.pop():
        log.warning("%s: the last line was cut short; its run will be done again", path)
    for n, raw in enumerate(lines, start=1):
        entry = _parse_legacy(raw)
        if entry is None:
            if raw.strip():
                log.warning("%s line %d: is damaged; its run will be done again", path, n)
            continue
        yield entry


def _parse_legacy(raw: bytes) -> tuple[str, dict[str, float]] | None:
    try:
        entry = json.loads(raw.decode("utf-8"))
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(entry, dict) or not isinstance(entry.get("key"), str):
        return None
    row = entry.get("row")
    if not isinstance(row, dict):
        return None
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in row.values()):
        return None
    return entry["key"], {str(k): float(v) for k, v in row.items()}


def stored_runs(folder: Path) -> int:
    """How many runs ``folder`` (``DIR/evals``) holds, read-only, for watching a study: the
    store's rows, or an earlier version's complete log lines."""
    path = Path(folder) / STORE_FILE
    if path.is_file():
        try:
            db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True, timeout=5.0)
            try:
                return int(db.execute("SELECT count(*) FROM runs").fetchone()[0])
            finally:
                db.close()
        except sqlite3.Error:
            return 0  # being created, or damaged: the study itself says which
    legacy = Path(folder) / LEGACY_FILE
    if not legacy.is_file():
        return 0
    return sum(1 for r in legacy.read_bytes().split(b"\n")[:-1] if _parse_legacy(r) is not None)


def stored_keys(folder: Path) -> set[str]:
    """The keys of the runs ``folder``'s store holds, read-only (for watching a study)."""
    path = Path(folder) / STORE_FILE
    if not path.is_file():
        return set()
    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True, timeout=5.0)
        try:
            return {str(k) for (k,) in db.execute("SELECT key FROM runs")}
        finally:
            db.close()
    except sqlite3.Error:
        return set()  # being created, or damaged: the study itself says which


def store_rows(folder: Path) -> list[dict[str, Any]]:
    """Every stored run of ``folder`` (``DIR/evals``) as a flat record: key, label, policy,
    seed, the point's values and the KPIs as columns (for ``export``); [] without a store."""
    path = Path(folder) / STORE_FILE
    if not path.is_file():
        return []
    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True, timeout=5.0)
        try:
            found = db.execute(f"SELECT {', '.join(COLUMNS)} FROM runs ORDER BY rowid").fetchall()
        finally:
            db.close()
    except sqlite3.Error as e:
        raise StudyError(f"{path}: cannot be read ({e}); move it away or rerun the study") from None
    out = []
    for key, label, point, policy, seed, kpis, special, finished_at in found:
        values = _loads(point) if point is not None else {}
        out.append(
            {
                "key": key,
                "label": label,
                **(values or {}),
                "policy": policy,
                "seed": seed,
                **(_loads(kpis, special) or {}),
                "finished_at": finished_at,
            }
        )
    return out
