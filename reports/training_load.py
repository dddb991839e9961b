"""Reading HDQN training runs (folders written by ``pnp-twin train``) for the training report.

A run folder holds ``meta.json`` (what was trained), ``log.csv`` (learning curve rows) and
``eval.csv`` (periodic validation); ``pnp-twin evaluate --out`` adds ``evaluation.csv``
(held-out gripping rate per policy and seed) and ``rules.csv`` (rule counts per robot).
Only ``meta.json`` is required; a missing table leaves its section out with a note.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from pnp_twin.reports.load import ReportError, read_json, read_table

log = logging.getLogger(__name__)

MODES = ("single", "sync", "async")
LOG_COLUMNS = {"step", "reward_per_step", "gripping_rate"}
EVAL_COLUMNS = {"step", "gripping_rate"}
EVALUATION_COLUMNS = {"policy", "kind", "seed", "gripping_rate"}
RULES_COLUMNS = {"robot", "rule", "count"}


@dataclass(frozen=True)
class TrainingRun:
    """One training run folder, as read from its files."""

    path: Path
    meta: dict[str, Any]
    log: pd.DataFrame | None = None
    eval: pd.DataFrame | None = None
    evaluation: pd.DataFrame | None = None
    rules: pd.DataFrame | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def mode(self) -> str:
        """The training set-up; "async (rollout)" for a run fitted to rollout targets."""
        mode = str(self.meta.get("mode") or "?")
        return f"{mode} (rollout)" if self.meta.get("targets") == "rollout" else mode

    @property
    def label(self) -> str:
        """'async · seed 1' (the folder name when the run does not say)."""
        seed = (self.meta.get("train_args") or {}).get("seed")
        return f"{self.mode} · seed {seed}" if seed is not None else self.path.name

    @property
    def scenario_name(self) -> str:
        scenario = self.meta.get("scenario") or {}
        return str(scenario.get("name") or self.path.name)


def is_run_folder(path: Path) -> bool:
    """A folder written by ``pnp-twin train``: its meta.json names a training mode."""
    meta = path / "meta.json"
    if not meta.is_file():
        return False
    try:
        data = read_json(meta)
    except ReportError:
        return False
    return "mode" in data and "kind" not in data  # studies write a kind, runs a mode


def run_folders(folder: Path | str) -> list[Path]:
    """``folder`` itself when it is a run, else the runs directly inside it, sorted by mode."""
    folder = Path(folder)
    if is_run_folder(folder):
        return [folder]
    if not folder.is_dir():
        return []
    found = [p for p in sorted(folder.iterdir()) if p.is_dir() and is_run_folder(p)]
    order = {m: i for i, m in enumerate(MODES)}
    return sorted(found, key=lambda p: (order.get(read_json(p / "meta.json")["mode"], 9), p.name))


def is_training_folder(folder: Path | str) -> bool:
    """Whether ``folder`` is a training run or holds some."""
    return bool(run_folders(folder))


def checked(table: pd.DataFrame | None, columns: set[str], name: str, notes: list[str]) -> Any:
    """``table`` when it has ``columns`` and rows, else None with a note saying why."""
    if table is None:
        return None
    missing = sorted(columns - set(table.columns))
    if missing:
        notes.append(f"{name} lacks column(s) {', '.join(missing)}: its section is left out.")
        return None
    if table.empty:
        notes.append(f"{name} has no rows: its section is left out.")
        return None
    return table


def load_run(folder: Path | str) -> TrainingRun:
    """Read one run folder; missing optional tables become notes."""
    folder = Path(folder)
    if not (folder / "meta.json").is_file():
        raise ReportError(f"{folder}: not a training run (no meta.json)")
    meta = read_json(folder / "meta.json")
    notes: list[str] = []
    tables = {}
    for stem, columns in (
        ("log", LOG_COLUMNS),
        ("eval", EVAL_COLUMNS),
        ("evaluation", EVALUATION_COLUMNS),
        ("rules", RULES_COLUMNS),
    ):
        tables[stem] = checked(read_table(folder, stem), columns, f"{stem}.csv", notes)
    absent = {
        "log": "No log.csv: the learning curves are left out.",
        "evaluation": "No evaluation.csv: the held-out comparison is left out "
        "(write it with `pnp-twin evaluate ... --out RUN`).",
        "rules": "No rules.csv: the rules chosen per robot are left out "
        "(written by `pnp-twin evaluate ... --out RUN`).",
    }
    for stem, note in absent.items():
        if tables[stem] is None and not (folder / f"{stem}.csv").is_file():
            notes.append(note)
    if tables["evaluation"] is not None:
        tables["evaluation"]["policy"] = tables["evaluation"]["policy"].astype(str)
    return TrainingRun(path=folder, meta=meta, notes=notes, **tables)


def load_runs(folder: Path | str) -> list[TrainingRun]:
    """Every run in ``folder`` (or the run it is); a ReportError when there is none."""
    paths = run_folders(folder)
    if not paths:
        raise ReportError(f"{folder}: neither a training run nor a folder of runs (no meta.json)")
    return [load_run(p) for p in paths]
