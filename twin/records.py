"""Records appended as events happen, turned into pandas DataFrames once at the end."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pandas as pd

from twin.belt import Belt

PART_COLUMNS = [
    "part",
    "fed_at",
    "y",
    "kind",
    "outcome",
    "robot",
    "rule",
    "decided_at",
    "picked_at",
    "placed_at",
    "blocked_time",
    "left_at",
]
SPAN_COLUMNS = ["robot", "state", "start", "end"]


class Recorder:
    """Per-part outcomes, robot state spans and decision counts of one run."""

    def __init__(self, n_parts: int) -> None:
        nan = math.nan
        self.robot = [-1] * n_parts
        self.rule: list[str | None] = [None] * n_parts
        self.decided_at = [nan] * n_parts
        self.picked_at = [nan] * n_parts
        self.placed_at = [nan] * n_parts
        self.blocked = [0.0] * n_parts
        self.spans: list[tuple[int, str, float, float]] = []
        self.decisions: Counter[tuple[int, str]] = Counter()

    def span(self, robot: int, state: str, start: float, end: float) -> None:
        if end > start:
            self.spans.append((robot, state, start, end))

    def parts_frame(self, belt: Belt, last_workspace_end: float) -> pd.DataFrame:
        """One row per part fed: outcome picked/missed; a missed part's left_at is when it
        passed the end of the last workspace."""
        fed = np.asarray(belt.fed, dtype=float)
        picked = np.asarray(self.picked_at, dtype=float)
        is_picked = ~np.isnan(picked)
        left = np.where(is_picked, picked, fed + last_workspace_end / belt.speed)
        robot = np.asarray(self.robot, dtype=np.int64)
        df = pd.DataFrame(
            {
                "part": np.arange(len(fed), dtype=np.int64),
                "fed_at": fed,
                "y": np.asarray(belt.y, dtype=float),
                "kind": belt.kind if belt.kind is not None else [""] * len(fed),
                "outcome": np.where(is_picked, "picked", "missed"),
                "robot": pd.array(np.where(is_picked, robot, -1), dtype="Int64"),
                "rule": [r if p else None for r, p in zip(self.rule, is_picked, strict=True)],
                "decided_at": np.where(is_picked, self.decided_at, np.nan),
                "picked_at": picked,
                "placed_at": np.asarray(self.placed_at, dtype=float),
                "blocked_time": np.asarray(self.blocked, dtype=float),
                "left_at": left,
            },
            columns=PART_COLUMNS,
        )
        df.loc[df["robot"] < 0, "robot"] = pd.NA
        return df

    def spans_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.spans, columns=SPAN_COLUMNS)

    def decisions_frame(self) -> pd.DataFrame:
        rows = [(r, rule, n) for (r, rule), n in sorted(self.decisions.items())]
        return pd.DataFrame(rows, columns=["robot", "rule", "count"])
