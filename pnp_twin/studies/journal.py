"""The resume journal of a study folder.

Finished runs are journaled by the coordinating process as results arrive, one row each in
the folder's runs store ``DIR/runs/runs.sqlite`` (:mod:`pnp_twin.studies.runstore`: SQLite
in WAL mode, keyed by the run id, each row committed on its own before :meth:`Journal.record`
returns), so an interrupted study (Ctrl-C, a killed process) loses no finished run. Rows are
fsynced at most half a second apart (the first commit half a second after the last fsync is
fsynced), so a power cut loses at most the runs of half a second while a study of runs that
take milliseconds does not wait for the disk at every run.
``DIR/study.json`` holds the study definition: re-running the same command skips finished
runs; a different definition in the same folder is refused (naming the fields that changed)
unless the caller asks for a fresh start. Only the replications may change: earlier runs
are kept and new ones added (their seeds do not depend on the count, so common random numbers
hold). Folders journaled by earlier versions (``DIR/runs/<run_id>.json`` per run, or segment
files ``DIR/runs/NNNNNN.jsonl``) are migrated on first resume
(:mod:`pnp_twin.studies.journal_legacy`: imported in one transaction, each file then renamed
``<name>.migrated``).

While a journal is open it holds the folder's lock (:mod:`pnp_twin.studies.lock`), so a
second process cannot write into the same folder. A fresh start moves the old study aside
into ``DIR/.replaced/`` and deletes it only once the new study has journaled its first
run; if the new one fails before that, the old study is put back.

Damaged rows: a stored row whose values are impossible (an edited row: G = 1234.5, a negative
count, another run's seed) is refused with one line naming the store, the run and the field;
a row that cannot be read at all is left out (a warning) and its run done again. A
``study.json`` that cannot be read is refused with one line.
"""

from __future__ import annotations

import json
import logging
import math
import re
import shutil
from collections.abc import Iterable, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

from pnp_twin.studies.execute import cell
from pnp_twin.studies.journal_legacy import (
    legacy_files,
    legacy_ids,
    mark_migrated,
    read_legacy_runs,
)
from pnp_twin.studies.lock import StudyLock
from pnp_twin.studies.plan import RunSpec, StudyError
from pnp_twin.studies.runstore import RunStore, stored_keys
from pnp_twin.twin.output import dumps_json, remove_temporaries, write_json

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
SYNC_SECONDS = 0.5  # rows are fsynced at most this long apart (each committed at once)


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
        self._store: RunStore | None = None  # opened (and an older folder migrated) on first use
        self._found: dict[str, dict[str, Any]] | None = None  # run_id -> row
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
        self._close_store()
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
        """The new study has journaled a run: delete the study a fresh start moved aside."""
        if self.replaced.is_dir():
            shutil.rmtree(self.replaced, ignore_errors=True)
            log.info("deleted the old study of %s", self.folder)

    def restore(self) -> None:
        """Put back the study a fresh start moved aside (the new one never ran)."""
        if not self.replaced.is_dir():
            return
        self._close_store()
        for name in OUTPUTS:
            p = self.folder / name
            if (self.replaced / name).exists():
                if p.is_dir():
                    shutil.rmtree(p)
                elif p.exists():
                    p.unlink()
                (self.replaced / name).rename(p)
        shutil.rmtree(self.replaced, ignore_errors=True)
        log.info("restored the earlier study of %s", self.folder)

    def close(self) -> None:
        """Close the store and release the folder's lock."""
        try:
            self._close_store()
        finally:
            self.lock.release()

    # -- the runs' rows: one committed row each in runs/runs.sqlite ----------------------
    def _close_store(self) -> None:
        if self._store is not None:
            self._store.close()
        self._store, self._found = None, None

    def _has_runs(self) -> bool:
        """Whether runs/ holds any journaled run: a stored row, or a complete, readable row of
        an earlier version's files (a line cut short by a kill is no run)."""
        return bool(journaled(self.runs))

    def _open_store(self) -> RunStore:
        """The store, an earlier version's files imported into it on first use."""
        if self._store is None:
            self.runs.mkdir(parents=True, exist_ok=True)
            store = RunStore(self.runs, sync_every=SYNC_SECONDS)
            try:
                self._migrate(store)
            except BaseException:
                store.close()
                raise
            self._store = store
        return self._store

    def _migrate(self, store: RunStore) -> None:
        files = legacy_files(self.runs)
        if not files:
            return
        found = read_legacy_runs(self.runs)
        store.add_many([(run_id, row, _about(row)) for run_id, row in found.items()])
        mark_migrated(files)
        log.info("%s: migrated %d runs into %s", self.runs, len(found), store.path)

    def _read(self) -> dict[str, dict[str, Any]]:
        """Every journaled row by run id (read from the store once, then kept up to date)."""
        if self._found is None:
            store = self._open_store()
            found = {}
            for run_id, row in store.items():
                if row is None:
                    log.warning("%s: run %s is damaged; running it again", store.path, run_id)
                else:
                    found[run_id] = row
            self._found = found
        return self._found

    def flush(self) -> None:
        """Nothing to write: each row is committed when it is recorded (kept for callers
        that make sure the rows are on disk before building the tables)."""

    def done(self) -> set[str]:
        """Ids of the journaled runs (not yet checked)."""
        return set(self._read())

    def record(self, row: Mapping[str, Any]) -> None:
        """Journal one finished run (NaN kept so the row reads back exactly), committed
        before this returns."""
        clean = json.loads(_dumps_row(row))  # plain Python values, as they read back
        found = self._read()
        self._open_store().add_many([(str(clean["run_id"]), clean, _about(clean))])
        found[str(clean["run_id"])] = clean

    def load(self, spec: RunSpec) -> dict[str, Any] | None:
        """``spec``'s journaled row, checked; None if not run yet (or its row was damaged)."""
        row = self._read().get(spec.run_id)
        if row is None:
            return None
        problem = row_problem(row, spec)
        if problem:
            path = self._open_store().path
            raise StudyError(
                f"{path} (run {spec.run_id}): {problem}; delete that run to run it again: "
                f"sqlite3 {path} \"DELETE FROM runs WHERE key = '{spec.run_id}'\""
            )
        return dict(row)

    def rows(self, specs: Iterable[RunSpec]) -> list[dict[str, Any] | None]:
        """The checked row of each spec (None where not run yet)."""
        return [self.load(s) for s in specs]


def _about(row: Mapping[str, Any]) -> dict[str, Any]:
    """The store's readable columns of a study row: the grid values, policy and seed."""
    ids = ("run_id", "point", "policy", "replication", "seed")
    point = {k: v for k, v in row.items() if "." in str(k) and k not in ids}
    return {
        "label": row.get("run_id"),
        "point": {"point": row.get("point"), **point},
        "policy": row.get("policy"),
        "seed": row.get("seed") if isinstance(row.get("seed"), int) else None,
    }


def _dumps_row(row: Mapping[str, Any]) -> str:
    """One JSON text (NaN as ``NaN``); plain rows skip the numpy / pandas conversion."""
    try:
        return json.dumps(row, allow_nan=True, separators=(",", ":"))
    except TypeError:
        return dumps_json(row, keep_nan=True)


def journaled(runs: Path) -> set[str]:
    """Run ids journaled in a ``runs/`` folder (the store's rows, and an earlier version's
    complete rows), without checking or changing anything: for watching a study."""
    return stored_keys(runs) | legacy_ids(runs)
