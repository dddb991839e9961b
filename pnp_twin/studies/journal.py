"""The resume journal of a study folder.

Each finished run is one small JSON file ``DIR/runs/<run_id>.json``, written atomically by
the coordinating process as results arrive, so an interrupted study (Ctrl-C, a killed
process) loses at most the runs in flight. ``DIR/study.json`` holds the study definition:
re-running the same command skips finished runs; a different definition in the same folder
is refused unless the caller asks for a fresh start.
"""

from __future__ import annotations

import json
import logging
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.studies.plan import StudyError
from twin.output import write_table, write_text

log = logging.getLogger(__name__)

DEFINITION = "study.json"
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


def write_json(path: Path, obj: Any) -> None:
    """Write ``obj`` as indented JSON, atomically; NaN stays NaN so rows round-trip exactly."""
    write_text(json.dumps(obj, indent=1, default=str) + "\n", path)


def write_frame(path: Path, frame: pd.DataFrame) -> None:
    """Write a DataFrame as Parquet or CSV (by suffix), atomically."""
    write_table(frame, path)


def _differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    keys = sorted(set(old) | set(new))
    return [k for k in keys if old.get(k) != new.get(k)]


class Journal:
    """The runs finished so far in one study folder."""

    def __init__(self, folder: Path, definition: dict[str, Any], fresh: bool = False) -> None:
        self.folder = Path(folder)
        self.runs = self.folder / "runs"
        # normalise through JSON so the comparison sees what a rerun will read back
        definition = json.loads(json.dumps(definition, default=str))
        stored = self.folder / DEFINITION
        if fresh:
            self.clear()
        elif stored.is_file():
            old = json.loads(stored.read_text(encoding="utf-8"))
            if old != definition:
                changed = ", ".join(_differences(old, definition)) or "the definition"
                raise StudyError(
                    f"--out {self.folder}: holds a different study (changed: {changed}); "
                    f"add --fresh to start it over or choose another folder"
                )
        elif self.runs.is_dir() and any(self.runs.iterdir()):
            raise StudyError(
                f"--out {self.folder}: has runs/ but no {DEFINITION}; add --fresh to start over"
            )
        self.runs.mkdir(parents=True, exist_ok=True)
        write_json(stored, definition)
        for tmp in self.runs.glob(".*.tmp"):  # left by a write that was killed mid-way
            tmp.unlink(missing_ok=True)

    def clear(self) -> None:
        """Remove the study outputs of this folder (nothing else in it)."""
        for name in OUTPUTS:
            p = self.folder / name
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()
        log.info("cleared study folder %s", self.folder)

    def done(self) -> set[str]:
        """Ids of the finished runs."""
        return {p.stem for p in self.runs.glob("*.json")}

    def record(self, row: dict[str, Any]) -> None:
        """Journal one finished run (atomically)."""
        write_json(self.runs / f"{row['run_id']}.json", row)

    def read(self, run_id: str) -> dict[str, Any]:
        """One finished run's row."""
        return json.loads((self.runs / f"{run_id}.json").read_text(encoding="utf-8"))

    def rows(self, keep: Callable[[str], bool] | None = None) -> list[dict[str, Any]]:
        """Every finished run's row (those whose id ``keep`` accepts), in id order."""
        out = []
        for p in sorted(self.runs.glob("*.json")):
            if keep is None or keep(p.stem):
                out.append(json.loads(p.read_text(encoding="utf-8")))
        return out
