"""The belt: the parts on it, their analytic positions, claims, grips and exits."""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Generator
from typing import TYPE_CHECKING, Any

import numpy as np
import simpy

from pnp_twin.twin.geometry import exit_time

if TYPE_CHECKING:
    from pnp_twin.twin.records import Recorder

FREE = -1
SWEEP = 5.0  # s between two sweeps of the belt's end by :meth:`Belt.conveying`


class Belt:
    """Parts on a conveyor moving at ``speed``; part i is at x = speed * (t - fed[i]).

    The feeder's whole stream is known up front (:meth:`load`: ``fed`` holds every arrival
    time, so a robot in a NooP knows when the next part comes), but a part is *on* the belt
    only once the feeder has put it there (:meth:`put`): queries never look past
    :attr:`arrived`. Parts are indexed in feeding order, so positions decrease with the
    index and the parts inside any stretch [x_lo, x_hi] form one index range (bisection).

    Robots go through :meth:`claim` (which also books the grip) and :meth:`release`.
    ``holder[i]`` is the robot that claimed or picked part i, or FREE; ``left_at[i]`` the
    time a claimed part is (or will be) gripped and leaves the belt. A part not gripped when
    it passes ``end`` (the end of the last workspace) is missed: :meth:`conveying` records it.
    """

    def __init__(
        self,
        length: float,
        width: float,
        speed: float,
        grid: tuple[int, int],
        end: float | None = None,
    ) -> None:
        self.length = length
        self.width = width
        self.speed = speed
        self.grid = grid
        self.end = length if end is None else end
        self.cell = length / grid[0]
        self.tick = self.cell / speed  # time the belt needs to move one grid cell
        self.fed: list[float] = []
        self.y: list[float] = []
        self.kind: list[str] | None = None
        self.kind_code: list[int] = []  # each part's kind code (index into feeder.kinds)
        self.holder: list[int] = []
        self.left_at: list[float] = []  # grip time of a claimed part, inf while on the belt
        self.arrived = 0  # parts the feeder has put on the belt so far

    def load(
        self,
        fed: np.ndarray,
        y: np.ndarray,
        kind: list[str] | None = None,
        codes: np.ndarray | None = None,
    ) -> None:
        """Announce the feeder's stream (each part is put on the belt at its fed time);
        ``codes``: each part's kind code (all 0 when not given)."""
        self.fed = fed.tolist()
        self.y = y.tolist()
        self.kind = kind
        self.kind_code = [0] * len(self.fed) if codes is None else codes.tolist()
        self.holder = [FREE] * len(self.fed)
        self.left_at = [math.inf] * len(self.fed)
        self.arrived = 0

    def __len__(self) -> int:
        return len(self.fed)

    # -- the feeder, the robots ---------------------------------------------------------------
    def put(self, upto: int) -> None:
        """The feeder has put parts [arrived, upto) on the belt at x = 0."""
        self.arrived = upto

    def claim(self, part: int, robot: int, grip_at: float) -> None:
        """``robot`` claims ``part``, to grip it at ``grip_at``: from then on the part is off
        the belt, unless the claim is released before (the grip itself needs no call)."""
        self.holder[part] = robot
        self.left_at[part] = grip_at

    def release(self, part: int) -> None:
        """A claim given up before the grip (t_any): the part is free again."""
        self.holder[part] = FREE
        self.left_at[part] = math.inf

    def exit_at(self, part: int) -> float:
        """When ``part`` passes the end of the last workspace (picked or not)."""
        return exit_time(self.fed[part], self.end, self.speed)

    def passed(self, now: float) -> int:
        """How many parts (the first ones fed) have passed the last workspace's end by now."""
        return bisect_right(self.fed, now - self.end / self.speed)

    def conveying(
        self, env: simpy.Environment, recorder: Recorder
    ) -> Generator[simpy.Event, Any, None]:
        """The belt's process: record the parts that pass the end unpicked, as missed.

        It sweeps the end of the belt every :data:`SWEEP` seconds and records each part that
        passed it unpicked since the last sweep, with its exact exit time (so the records do
        not depend on the sweep period; waking once per part would cost more than the rest
        of the model). A part still claimed at its exit is gripped there (to rounding).
        """
        fed, holder = self.fed, self.holder
        lag = self.end / self.speed  # fed + lag is geometry.exit_time, inlined
        i, n = 0, len(fed)
        while i < n:
            yield env.timeout(SWEEP)
            now = env.now
            while i < n and fed[i] + lag <= now:
                if holder[i] == FREE:
                    recorder.missed(i, fed[i] + lag)
                i += 1

    # -- what robots and cameras see ----------------------------------------------------------
    def span(self, now: float, x_lo: float, x_hi: float) -> range:
        """Indices of the parts on the belt at ``now`` with x in [x_lo, x_hi]."""
        v, arrived = self.speed, self.arrived
        lo = bisect_left(self.fed, now - x_hi / v)
        hi = bisect_right(self.fed, now - (x_lo if x_lo > 0.0 else 0.0) / v)
        return range(lo, hi if hi < arrived else arrived)

    def next_entry(self, now: float, x: float) -> float:
        """Time until the next unclaimed part upstream of ``x`` reaches it (inf if none).

        Parts the feeder has not put on the belt yet count: its schedule is known.
        """
        v = self.speed
        fed, holder = self.fed, self.holder
        lag = x / v
        i = bisect_right(fed, now - lag)
        n = len(fed)
        # a part at x (to rounding) has already entered: waiting for it would take no time
        while i < n and (holder[i] != FREE or fed[i] + lag <= now):
            i += 1
        if i >= n:
            return math.inf
        return fed[i] + lag - now

    def on_belt(self, now: float) -> range:
        """Indices that may be on the belt at ``now`` (fed, not past its length); a part in
        it is still on the belt when ``left_at[i] > now`` (not gripped yet)."""
        lo = bisect_left(self.fed, now - self.length / self.speed)
        return range(lo, min(bisect_right(self.fed, now), self.arrived))

    def image(
        self,
        now: float,
        x_lo: float = 0.0,
        x_hi: float | None = None,
        cells: tuple[int, int] | None = None,
        free_only: bool = False,
    ) -> np.ndarray:
        """Occupancy grid (cells across, cells along) of the stretch [x_lo, x_hi] at ``now``.

        Row 0 is the lower belt edge; column 0 is x_lo. A part is on the belt from its fed
        time until it is gripped; with ``free_only`` claimed parts are left out too.
        """
        x_hi = self.length if x_hi is None else x_hi
        nx, ny = cells or self.grid
        out = np.zeros((ny, nx), dtype=np.uint8)
        rng = self.span(now, x_lo, x_hi)
        if not len(rng):
            return out
        s = slice(rng.start, rng.stop)
        fed = np.asarray(self.fed[s])
        ys = np.asarray(self.y[s])
        if free_only:
            keep = np.asarray(self.holder[s]) == FREE
        else:
            keep = np.asarray(self.left_at[s]) > now
        xs = self.speed * (now - fed[keep])
        col = np.minimum(((xs - x_lo) * (nx / (x_hi - x_lo))).astype(np.int64), nx - 1)
        row = np.minimum((ys[keep] * (ny / self.width)).astype(np.int64), ny - 1)
        out[row, col] = 1
        return out
