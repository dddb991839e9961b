"""Conditions a design must meet its target at (``--across PATH=V1,V2,...``): the flows the
line will see, each shift's recorded trace. A condition is not bought: every configuration
is run at every condition, and it meets the target only where it meets it at all of them.

``--across feeder.trace=DIR`` makes each ``*.csv`` trace of the folder one condition (each
shift replayed as recorded; the interval is then about the runs' own randomness at that
shift). Several ``--across`` fields give every combination of their values.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

from pnp_twin.studies.plan import StudyError, field_path_error
from pnp_twin.studies.vary import parse_vary
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import trace_paths

CONDITION_PREFIXES = ("feeder.",)  # what arrives on the belt: the plant's, not bought
MAX_CONDITIONS = 100


def is_condition(path: str) -> bool:
    """Whether ``path`` is a condition of the plant (what arrives), not a purchase."""
    return path.startswith(CONDITION_PREFIXES)


def _values(spec: str, path: str, text: str, scenario: Scenario) -> list[Any]:
    if path == "feeder.trace":
        names = [t.strip() for t in text.split(",") if t.strip()]
        try:
            files = trace_paths(names, scenario.source_dir)
        except UserError as e:
            raise StudyError(f"--across {spec}: {e}") from None
        missing = [f for f in files if not f.is_file()]
        if not files or missing:
            raise StudyError(
                f"--across {spec}: '{missing[0] if missing else text}' is not a trace file; "
                "give trace files or a folder of time,y[,kind] CSV files"
            )
        return [str(f.resolve()) for f in dict.fromkeys(Path(f).resolve() for f in files)]
    _, values = parse_vary(spec)
    if not isinstance(values, list):
        raise StudyError(
            f"--across {spec}: give the values the line will see (V1,V2,... or a range of "
            "whole numbers), not a continuous range"
        )
    return values


def parse_across(specs: Any, scenario: Scenario) -> dict[str, list[Any]]:
    """``--across`` options as {path: values}; a path given twice, or one that is not a
    scenario field, is refused in one line."""
    grid: dict[str, list[Any]] = {}
    for spec in specs or ():
        path, sep, text = str(spec).partition("=")
        path = path.strip()
        if not sep or not path or not text.strip():
            raise StudyError(f"--across {spec!r}: give PATH=V1,V2,... (e.g. feeder.rate=6,7,8)")
        problem = field_path_error(path)
        if problem:
            raise StudyError(problem.replace("sweep.grid", "--across"))
        if path in grid:
            raise StudyError(f"--across {path}: given twice; give each field once")
        grid[path] = _values(spec, path, text, scenario)
    return grid


def conditions_of(scenario: Scenario, grid: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """Every combination of the conditions' values ([{}]: the line as it is, without any);
    at most :data:`MAX_CONDITIONS`."""
    count = 1
    for values in grid.values():
        count *= len(values)
    if count > MAX_CONDITIONS:
        raise StudyError(
            f"--across: {count} conditions; at most {MAX_CONDITIONS}: give fewer values"
        )
    extra: dict[str, Any] = {}
    if "feeder.trace" in grid and scenario.feeder.arrival != "trace":
        extra = {"feeder.arrival": "trace"}
    combos = [dict(zip(grid, c, strict=True)) for c in itertools.product(*grid.values())]
    return [{**extra, **c} if c else c for c in combos]
