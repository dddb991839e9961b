"""Running a study into its folder: plan -> journal -> backend -> tables -> files."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pnp_twin.studies.backends import run_specs
from pnp_twin.studies.folder import (
    Tables,
    build_tables,
    meta,
    now_iso,
    representative,
    write_records,
    write_tables,
)
from pnp_twin.studies.journal import Journal, write_json
from pnp_twin.studies.plan import RunSpec, StudyPlan

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
"""Called with (runs done, runs planned): once at the start, then after each run."""


@dataclass
class Options:
    """How to run: backend, workers, cluster address, fresh start, progress callback."""

    backend: str = "local"
    workers: int = 1
    address: str | None = None
    fresh: bool = False
    progress: Progress | None = None
    command: str = ""
    confidence: float = 0.95


@dataclass
class Session:
    """A journal plus the options: runs specs, skipping the finished ones."""

    journal: Journal
    options: Options
    planned: int = 0
    done: int = 0
    skipped: int = 0
    ran: int = 0
    started: float = field(default_factory=time.perf_counter)
    started_at: str = field(default_factory=now_iso)

    def plan_more(self, n: int) -> None:
        """Announce ``n`` more runs (the rule-mix search plans batch by batch)."""
        self.planned += n
        self._report()

    def _report(self) -> None:
        if self.options.progress is not None:
            self.options.progress(self.done, self.planned)

    def run(self, specs: Sequence[RunSpec]) -> list[dict[str, Any]]:
        """Rows of ``specs`` (in order), running those not yet journaled."""
        finished = self.journal.done()
        todo = [s for s in specs if s.run_id not in finished]
        self.skipped += len(specs) - len(todo)
        self.done += len(specs) - len(todo)
        self._report()

        def on_row(row: dict[str, Any]) -> None:
            self.journal.record(row)
            self.done += 1
            self.ran += 1
            self._report()

        o = self.options
        run_specs(todo, on_row, o.backend, o.workers, o.address)
        return [self.journal.read(s.run_id) for s in specs]

    def meta_extra(self) -> dict[str, Any]:
        o = self.options
        return {
            "started_at": self.started_at,
            "finished_at": now_iso(),
            "wall_time": time.perf_counter() - self.started,
            "workers": o.workers,
            "backend": o.backend,
            "command": o.command,
            "confidence": o.confidence,
            "runs_skipped": self.skipped,
            "runs_executed": self.ran,
        }


def open_session(
    out: Path, plan: StudyPlan, kind: str, options: Options, extra: dict[str, Any] | None = None
) -> Session:
    """Open (or resume) the study folder ``out`` for ``plan``."""
    definition = {"kind": kind, **plan.definition(), **(extra or {})}
    return Session(Journal(Path(out), definition, fresh=options.fresh), options)


def finish(
    session: Session,
    plan: StudyPlan,
    kind: str,
    rows: Sequence[dict[str, Any]],
    extra_meta: dict[str, Any] | None = None,
) -> Tables:
    """Write the tables, the representative run's records and meta.json."""
    folder = session.journal.folder
    tables = build_tables(rows, list(plan.grid), session.options.confidence)
    write_tables(folder, tables)
    write_records(folder, representative(plan, tables.best))
    extra = {**session.meta_extra(), **(extra_meta or {})}
    write_json(folder / "meta.json", meta(plan, kind, **extra))
    log.info("study %s: %d runs (%d resumed) in %s", kind, len(rows), session.skipped, folder)
    return tables


def run_sweep(plan: StudyPlan, out: Path, options: Options) -> Tables:
    """Run every point x policy x replication of ``plan`` into ``out``."""
    session = open_session(out, plan, "sweep", options)
    specs = plan.specs()
    session.plan_more(len(specs))
    rows = session.run(specs)
    return finish(session, plan, "sweep", rows)
