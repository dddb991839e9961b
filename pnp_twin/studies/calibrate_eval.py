"""Predictions of a calibration: a line's KPIs at measured points, cached in a journal.

The prediction at a point is the KPI under the best of the given policies there (by mean
gripping rate over the replications, as a measured line runs its best rule), averaged over
replications that use common random numbers: replication k of every point, policy and
parameter vector sees the same part stream, so the objective changes smoothly with the
parameters instead of jumping with the noise.

Every run is stored the moment it finishes, in ``DIR/evals/runs.sqlite``
(:mod:`pnp_twin.studies.runstore`: one committed SQLite row per run, keyed by the run's
resolved scenario, policy, seed and KPIs), and every finished point atomically as
``DIR/evals/<key>.json``, where the key hashes exactly what was simulated (the point's
resolved scenario, the policies, the seeds, the KPIs). A rerun of an interrupted fit, design
or capacity search replays the finished points and runs without simulating them again,
down to the runs of a point that was cut short half-way.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Mapping, Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.parallel import pool_map
from pnp_twin.studies.backends import Executor
from pnp_twin.studies.execute import execute
from pnp_twin.studies.plan import RunSpec, StudyError
from pnp_twin.studies.runstore import RunStore
from pnp_twin.twin.output import write_text
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

log = logging.getLogger(__name__)

EVALS = "evals"
BEST_BY = "gripping_rate"
POOL_MIN_RUNS = 8  # runs per worker below which a batch runs in-process


@dataclass(frozen=True)
class PointPrediction:
    """What the twin predicts at one point: the best policy, and per KPI mean and CI."""

    policy: str
    mean: dict[str, float]
    ci_low: dict[str, float]
    ci_high: dict[str, float]


def _key(
    scenario: Scenario, policies: Sequence[str], seeds: Sequence[int], kpis: Sequence[str]
) -> str:
    what = {
        "scenario": scenario.model_dump(mode="json", exclude={"source_dir", "name", "description"}),
        "policies": list(policies),
        "seeds": list(seeds),
        "kpis": list(kpis),
    }
    text = json.dumps(what, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:20]


def _run_key(scene: dict[str, Any], policy: str, seed: int, kpis: Sequence[str]) -> str:
    """The per-run log's key of one run: its resolved scenario, policy, seed and KPIs."""
    what = {"scenario": scene, "policy": policy, "seed": seed, "kpis": list(kpis)}
    text = json.dumps(what, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:24]


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _split(run_id: str) -> tuple[int, str, int]:
    """'3|SPT|1' -> (point 3, policy SPT, replication 1)."""
    i, p, k = run_id.split("|")
    return int(i), p, int(k)


def _summarise(runs: dict[str, list[dict[str, float]]], kpis: Sequence[str]) -> PointPrediction:
    """The best policy's mean and t-interval per KPI (ties: the first policy given)."""
    means = {p: float(np.mean([r[BEST_BY] for r in rows])) for p, rows in runs.items()}
    best = max(means, key=lambda p: means[p])
    mean, low, high = {}, {}, {}
    for k in kpis:
        m, lo, hi = t_interval([r[k] for r in runs[best]])
        mean[k], low[k], high[k] = m, lo, hi
    return PointPrediction(best, mean, low, high)


def _read_journal(path: Path) -> dict[str, list[dict[str, float]]] | None:
    """A journalled point's runs; None when absent. A damaged file (a kill mid-write on a
    file system without atomic rename, an edit) is removed, so the point is simulated again."""
    if not path.is_file():
        return None
    try:
        runs = json.loads(path.read_text(encoding="utf-8"))["runs"]
        if not isinstance(runs, dict):
            raise TypeError("runs is not an object")
        return runs
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as e:
        log.warning("%s: damaged (%s); simulating the point again", path, e)
        path.unlink(missing_ok=True)
        return None


class Evaluator:
    """Simulates points (policies x replications each), through the journal in ``folder``."""

    def __init__(
        self,
        folder: Path,
        policies: Sequence[str],
        seeds: Sequence[int],
        kpis: Sequence[str],
        workers: int = 1,
        engine: str = "auto",
        store: RunStore | None = None,
        executor: Executor | None = None,
    ) -> None:
        self.folder = Path(folder) / EVALS
        self.policies = tuple(policies)
        self.seeds = tuple(seeds)
        self.kpis = tuple(dict.fromkeys([BEST_BY, *kpis]))
        self.workers = workers
        self.engine = engine  # twin.run.simulate's engine (same results either way)
        self.engines_ran: set[str] = set()  # the engines that simulated this evaluator's runs
        self.simulated = 0  # points simulated by this evaluator (not replayed)
        self.replayed = 0
        # every run, committed as it finishes; a caller evaluating many batches passes one
        # store in, so it is opened (and an older folder's log migrated) once
        self.store = store if store is not None else RunStore(self.folder)
        self.runs_simulated = 0  # runs simulated now; the others of a simulated point came
        self.runs_replayed = 0  # from the runs store (a point cut short by a kill)
        self.runs_from_points = 0  # the runs of whole points read back from the journal
        self.executor = executor  # one pool (or Ray session) for a whole study, if given

    def predict(
        self, scenarios: Sequence[Scenario], labels: Sequence[str]
    ) -> list[PointPrediction]:
        """The prediction at each scenario; journalled ones are read back, not simulated."""
        return [_summarise(r, self.kpis) for r in self.runs(scenarios, labels)]

    def runs(
        self,
        scenarios: Sequence[Scenario],
        labels: Sequence[str],
        points: Sequence[Mapping[str, Any]] | None = None,
    ) -> list[dict[str, list[dict[str, float]]]]:
        """Each scenario's runs ({policy: one row of KPIs per replication}), read back from
        the journal where it holds them, else simulated and journalled (with its ``points``'
        values, the configuration, in the store's ``point`` column)."""
        keys = [_key(s, self.policies, self.seeds, self.kpis) for s in scenarios]
        runs: dict[int, dict[str, list[dict[str, float]]]] = {}
        todo = []
        for i, key in enumerate(keys):
            stored = _read_journal(self.folder / f"{key}.json")
            if stored is not None:
                runs[i] = stored
                self.replayed += 1
                self.runs_from_points += sum(len(rows) for rows in stored.values())
            else:
                todo.append(i)
        if todo:
            fresh = self._simulate(
                [scenarios[i] for i in todo],
                [labels[i] for i in todo],
                None if points is None else [points[i] for i in todo],
            )
            for i, result in zip(todo, fresh, strict=True):
                runs[i] = result
                record = {"label": labels[i], "policies": list(self.policies), "runs": result}
                write_text(json.dumps(record) + "\n", self.folder / f"{keys[i]}.json")
                self.simulated += 1
        return [runs[i] for i in range(len(scenarios))]

    def _replay(
        self, scenarios: Sequence[Scenario], out: list[dict[str, list[Any]]]
    ) -> dict[str, str]:
        """Fill ``out`` with the runs the store holds; the others' run ids and keys."""
        keys: dict[str, str] = {}
        for i, sc in enumerate(scenarios):
            scene = sc.model_dump(mode="json", exclude={"source_dir", "name", "description"})
            for p in self.policies:
                for k, seed in enumerate(self.seeds):
                    key = _run_key(scene, p, seed, self.kpis)
                    stored = self.store.get(key)
                    if stored is not None and all(_number(stored.get(c)) for c in self.kpis):
                        out[i][p][k] = {c: float(stored[c]) for c in self.kpis}
                        self.runs_replayed += 1
                    else:
                        keys[f"{i}|{p}|{k}"] = key
        return keys

    def _simulate(
        self,
        scenarios: Sequence[Scenario],
        labels: Sequence[str],
        points: Sequence[Mapping[str, Any]] | None = None,
    ) -> list[dict[str, list[dict[str, float]]]]:
        """Each scenario's runs: those in the store read back, the others simulated and
        stored one by one as they finish."""
        out: list[dict[str, list[Any]]] = [
            {p: [None] * len(self.seeds) for p in self.policies} for _ in scenarios
        ]
        keys = self._replay(scenarios, out)  # run_id -> the store's key, of runs to do
        specs = [
            RunSpec(run_id, i, {}, p, k, self.seeds[k], scenarios[i], engine=self.engine)
            for run_id in keys
            for i, p, k in [_split(run_id)]
        ]

        def keep(row: dict[str, Any]) -> None:
            i, p, k = _split(row["run_id"])
            missing = [c for c in self.kpis if c not in row]
            if missing:
                raise StudyError(
                    f"point {labels[i]}: the line has no KPI {missing[0]} (robot KPIs "
                    f"r<i>_... need robot i on the line)"
                )
            out[i][p][k] = {c: float(row[c]) for c in self.kpis}
            point = None if points is None else points[i]
            self.store.add(
                keys[row["run_id"]], out[i][p][k], label=labels[i], point=point, policy=p,
                seed=self.seeds[k],
            )  # fmt: skip
            self.runs_simulated += 1
            self.engines_ran.add(str(row.get("engine", "simpy")))

        try:
            if self.executor is not None:
                self.executor.run(specs, keep)
            # a fresh pool costs a second or two to start: worth it only for a big batch
            elif self.workers > 1 and len(specs) >= POOL_MIN_RUNS * self.workers:
                pool_map(execute, specs, keep, self.workers, preload=["pnp_twin.studies.execute"])
            else:
                for spec in specs:
                    keep(execute(spec))
        except StudyError:
            raise
        except BrokenProcessPool:
            raise StudyError(
                "a worker process ended abruptly (killed, or out of memory); rerun the same "
                "command to resume from the journal, or use --workers 1"
            ) from None
        except Exception as e:  # a line the twin cannot run is the user's point, not a crash
            log.debug("simulation failed", exc_info=True)
            where = labels[0] if len(labels) == 1 else f"one of {', '.join(labels)}"
            raise StudyError(
                f"point {where} cannot be simulated: {type(e).__name__}: {e}"
            ) from None
        return out
