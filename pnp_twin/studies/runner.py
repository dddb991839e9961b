"""Running a study into its folder: plan -> journal -> backend -> tables -> files.

A session holds the folder's lock from :func:`open_session` to :func:`finish` (or to the
first error). With ``replications = "auto"`` (:class:`~pnp_twin.studies.plan.Precision`)
:func:`run_plan` runs the replications in rounds until every point x policy's CI
half-width of the gripping rate meets the target, and ``meta.json`` states the precision
reached (``precision``, see ``docs/study_format.md``).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from pnp_twin.studies.backends import run_specs
from pnp_twin.studies.costing import study_costs
from pnp_twin.studies.folder import (
    Tables,
    build_tables,
    meta,
    now_iso,
    representative,
    write_records,
    write_tables,
)
from pnp_twin.studies.journal import Journal
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.studies.plan import RunSpec, StudyPlan
from pnp_twin.twin.output import write_json
from pnp_twin.twin.stats import t_interval

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
    engine: str = "auto"  # simulation engine of every run (results are identical)
    costs: dict[str, Any] | None = None  # --costs: prices (studies.design.read_costs)
    costs_file: str = ""
    kpi: KpiChoice = GRIPPING  # --kpi of size: the figure the target is on (an analysis setting)


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
    precision: dict[str, Any] | None = None

    def plan_more(self, n: int) -> None:
        """Announce ``n`` more runs (the rule-mix search plans batch by batch)."""
        self.planned += n
        self._report()

    def _report(self) -> None:
        if self.options.progress is not None:
            self.options.progress(self.done, self.planned)

    def run(self, specs: Sequence[RunSpec]) -> list[dict[str, Any]]:
        """Rows of ``specs`` (in order), running those not yet journaled."""
        try:
            return self._run(specs)
        except BaseException:
            if self.ran == 0:  # a fresh start that never ran: the old study comes back
                self.journal.restore()
            self.close()
            raise

    def _run(self, specs: Sequence[RunSpec]) -> list[dict[str, Any]]:
        found = self.journal.rows(specs)
        todo = [s for s, row in zip(specs, found, strict=True) if row is None]
        self.skipped += len(specs) - len(todo)
        self.done += len(specs) - len(todo)
        self._report()

        def on_row(row: dict[str, Any]) -> None:
            self.journal.record(row)
            if self.ran == 0:
                self.journal.started()
            self.done += 1
            self.ran += 1
            self._report()

        o = self.options
        todo = [replace(s, engine=o.engine) for s in todo]
        if todo and o.engine != "simpy" and o.workers > 1:
            from pnp_twin.twin.fast import prepare

            prepare()  # compile (or load) the fast kernel once, not in every worker
        run_specs(todo, on_row, o.backend, o.workers, o.address)
        rows = self.journal.rows(specs)
        missing = [s.run_id for s, row in zip(specs, rows, strict=True) if row is None]
        if missing:
            raise RuntimeError(f"runs not journaled: {', '.join(missing[:3])}")
        return [row for row in rows if row is not None]

    def close(self) -> None:
        """Release the folder (its lock); the session cannot run after this."""
        self.journal.close()

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
            "engine": o.engine,
            "runs_skipped": self.skipped,
            "runs_executed": self.ran,
            **({"precision": self.precision} if self.precision else {}),
        }


def open_session(
    out: Path, plan: StudyPlan, kind: str, options: Options, extra: dict[str, Any] | None = None
) -> Session:
    """Open (or resume) the study folder ``out`` for ``plan``."""
    definition = {"kind": kind, **plan.definition(), **(extra or {})}
    journal = Journal(Path(out), definition, fresh=options.fresh, command=options.command)
    return Session(journal, options)


def half_widths(
    rows: Sequence[dict[str, Any]], kpi: str, confidence: float
) -> dict[tuple[int, str], float]:
    """The CI half-width of ``kpi``'s mean at each (point, policy); NaN below 2 values."""
    values: dict[tuple[int, str], list[float]] = {}
    for r in rows:
        values.setdefault((int(r["point"]), str(r["policy"])), []).append(float(r[kpi]))
    out = {}
    for key, xs in values.items():
        _, low, high = t_interval(xs, confidence)
        out[key] = (high - low) / 2.0
    return out


def next_count(n: int, widths: Sequence[float], target: float, top: int) -> int:
    """Replications for the next round: the usual n (h / h*)^2 estimate, at most doubling."""
    need = n + 1
    for h in widths:
        if math.isfinite(h) and h > target:
            need = max(need, math.ceil(n * (h / target) ** 2))
    return min(top, max(n + 1, min(2 * n, need)))


def run_plan(session: Session, plan: StudyPlan) -> tuple[StudyPlan, list[dict[str, Any]]]:
    """Run ``plan`` (in rounds if its replications are "auto"); the plan as run and rows."""
    specs = plan.specs()
    session.plan_more(len(specs))
    rows = session.run(specs)
    p = plan.precision
    if p is None:
        return plan, rows
    rounds = [plan.replications]
    while True:
        widths = half_widths(rows, p.kpi, session.options.confidence)
        # a point whose KPI is undefined (no part presented) gains nothing from more runs
        undefined = sum(1 for h in widths.values() if not math.isfinite(h))
        short = [h for h in widths.values() if math.isfinite(h) and h > p.half_width]
        n = plan.replications
        if not short or n >= p.max_replications:
            break
        plan = plan.with_replications(next_count(n, short, p.half_width, p.max_replications))
        added = [s for s in plan.specs() if s.replication >= n]
        session.plan_more(len(added))
        rows += session.run(added)
        rounds.append(plan.replications)
        log.info("replications: round %d, %d per point", len(rounds), plan.replications)
    worst = max(widths, key=lambda k: widths[k] if math.isfinite(widths[k]) else math.inf)
    session.precision = {
        "kpi": p.kpi,
        "target_half_width": p.half_width,
        "max_replications": p.max_replications,
        "confidence": session.options.confidence,
        "replications": plan.replications,
        "rounds": rounds,
        "reached": not short and not undefined,
        "points_short": len(short),
        "points_undefined": undefined,
        "half_width_max": widths[worst],
        "worst": {"point": worst[0], "policy": worst[1]},
    }
    return plan, rows


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
    write_records(folder, replace(representative(plan, tables.best), engine=session.options.engine))
    extra = {**session.meta_extra(), **(extra_meta or {})}
    o = session.options
    if o.costs is not None:  # an analysis setting: what each point x policy costs
        extra["costs"] = study_costs(plan, tables, o.costs, o.costs_file)
    write_json(meta(plan, kind, **extra), folder / "meta.json", keep_nan=True)
    session.journal.started()
    session.close()
    log.info("study %s: %d runs (%d resumed) in %s", kind, len(rows), session.skipped, folder)
    return tables


def run_sweep(plan: StudyPlan, out: Path, options: Options) -> Tables:
    """Run every point x policy x replication of ``plan`` into ``out``."""
    session = open_session(out, plan, "sweep", options)
    try:
        plan, rows = run_plan(session, plan)
        return finish(session, plan, "sweep", rows)
    finally:
        session.close()
