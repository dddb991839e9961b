"""Records appended as events happen, turned into pandas DataFrames once at the end.

Inside the run robots are indexed from 0; the DataFrames number them from 1, as every
table, override and report does (robot 1 is the most upstream).
"""

from __future__ import annotations

import math
from collections import Counter
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from pnp_twin.twin.geometry import exit_time

if TYPE_CHECKING:
    import pandas as pd


class FedParts(Protocol):
    """What :meth:`Recorder.parts_frame` reads of a belt (:class:`twin.belt.Belt`, or the
    fast engine's view of its arrays): a protocol, so this module does not import the belt
    that records into it."""

    @property
    def fed(self) -> npt.ArrayLike: ...
    @property
    def y(self) -> npt.ArrayLike: ...
    @property
    def kind(self) -> list[str] | None: ...
    @property
    def speed(self) -> float: ...


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
OUTFEED_COLUMNS = ["container", "slot", "held_at", "hold_time"]
"""Appended to the parts table on a line with an outfeed (and only there)."""
SPAN_COLUMNS = ["robot", "state", "start", "end"]


class Recorder:
    """Per-part outcomes, robot state spans and decision counts of one run.

    Robots, the gateway and the belt report through its methods; the lists are read only.
    """

    def __init__(self, n_parts: int, outfeed: bool = False) -> None:
        """``outfeed``: the line places onto an outfeed; each part's container, slot and
        hold are recorded too (:data:`OUTFEED_COLUMNS`)."""
        nan = math.nan
        self.robot = [-1] * n_parts
        self.rule: list[str | None] = [None] * n_parts
        self.decided_at = [nan] * n_parts
        self.picked_at = [nan] * n_parts
        self.placed_at = [nan] * n_parts
        self.blocked = [0.0] * n_parts
        self.missed_at = [nan] * n_parts
        self.spans: list[tuple[int, str, float, float]] = []
        self.decisions: Counter[tuple[int, str]] = Counter()
        self.open: dict[int, tuple[str, float]] = {}  # robot -> (state, since): not yet ended
        self.outfeed = outfeed
        self.container = [-1] * n_parts if outfeed else []
        self.slot = [-1] * n_parts if outfeed else []
        self.held_at = [nan] * n_parts if outfeed else []  # a hold for a free slot began
        self.hold_time = [0.0] * n_parts if outfeed else []  # s it lasted (once placed)

    def begin(self, robot: int, state: str, start: float) -> None:
        """A long state (down, wait) starts: kept open so a run ending inside it counts it."""
        self.open[robot] = (state, start)

    def span(self, robot: int, state: str, start: float, end: float) -> None:
        if self.open and self.open.get(robot) == (state, start):
            del self.open[robot]
        if end > start:
            self.spans.append((robot, state, start, end))

    def close_open_spans(self, now: float) -> None:
        """End every state still open at ``now`` (the end of the run), e.g. a long repair."""
        for robot, (state, start) in sorted(self.open.items()):
            self.span(robot, state, start, now)

    def decided(self, robot: int, rule: str) -> None:
        """A decision of ``robot`` with candidates, answered by ``rule`` (or "?")."""
        self.decisions[(robot, rule)] += 1

    def noop(self, robot: int) -> None:
        """A decision of ``robot`` without candidates: a NooP."""
        self.decisions[(robot, "NooP")] += 1

    def picked(
        self, part: int, robot: int, rule: str | None, decided_at: float, picked_at: float
    ) -> None:
        """``robot`` gripped ``part`` at ``picked_at``, decided at ``decided_at`` by ``rule``."""
        self.robot[part] = robot
        self.rule[part] = rule
        self.decided_at[part] = decided_at
        self.picked_at[part] = picked_at

    def placed(self, part: int, placed_at: float, blocked: float) -> None:
        """``part`` went into its bin at ``placed_at``, after ``blocked`` s of box change."""
        self.placed_at[part] = placed_at
        if blocked > 0.0:
            self.blocked[part] = blocked

    def held(self, part: int, at: float) -> None:
        """``part``'s robot found no free slot in reach at ``at`` and holds it."""
        self.held_at[part] = at

    def slotted(self, part: int, container: int, slot: int, hold_time: float) -> None:
        """``part`` goes into ``slot`` of ``container`` after holding ``hold_time`` s."""
        self.container[part] = container
        self.slot[part] = slot
        self.hold_time[part] = hold_time

    def missed(self, part: int, at: float) -> None:
        """``part`` passed the end of the last workspace unpicked at ``at`` (the belt)."""
        self.missed_at[part] = at

    def parts_frame(self, belt: FedParts, last_workspace_end: float) -> pd.DataFrame:
        """One row per part fed: outcome picked/missed; a missed part's left_at is when it
        passed the end of the last workspace (as the belt recorded it; parts still on the
        belt when a run is cut short get the time they will pass it)."""
        fed = np.asarray(belt.fed, dtype=float)
        picked = np.asarray(self.picked_at, dtype=float)
        is_picked = ~np.isnan(picked)
        missed = np.asarray(self.missed_at, dtype=float)
        exits = np.where(np.isnan(missed), exit_time(fed, last_workspace_end, belt.speed), missed)
        left = np.where(is_picked, picked, exits)
        robot = np.asarray(self.robot, dtype=np.int64)
        import pandas as pd  # only when a table is asked for

        df = pd.DataFrame(
            {
                "part": np.arange(len(fed), dtype=np.int64),
                "fed_at": fed,
                "y": np.asarray(belt.y, dtype=float),
                "kind": belt.kind if belt.kind is not None else [""] * len(fed),
                "outcome": np.where(is_picked, "picked", "missed"),
                "robot": pd.array(np.where(is_picked, robot + 1, -1), dtype="Int64"),
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
        if self.outfeed:
            df["container"] = pd.array(np.asarray(self.container, dtype=np.int64), dtype="Int64")
            df["slot"] = pd.array(np.asarray(self.slot, dtype=np.int64), dtype="Int64")
            df.loc[df["container"] < 0, ["container", "slot"]] = pd.NA
            df["held_at"] = np.asarray(self.held_at, dtype=float)
            df["hold_time"] = np.asarray(self.hold_time, dtype=float)
        return df

    def spans_frame(self) -> pd.DataFrame:
        import pandas as pd

        df = pd.DataFrame(self.spans, columns=SPAN_COLUMNS)
        df["robot"] = df["robot"].astype(np.int64) + 1
        return df

    def decisions_frame(self) -> pd.DataFrame:
        rows = [(r + 1, rule, n) for (r, rule), n in sorted(self.decisions.items())]
        import pandas as pd

        return pd.DataFrame(rows, columns=["robot", "rule", "count"])
