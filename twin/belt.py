"""The belt: the parts on it, their analytic positions, claims and outcomes."""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right

import numpy as np

FREE = -1


class Belt:
    """Parts on a conveyor moving at ``speed``; part i is at x = speed * (t - fed[i]).

    Parts are indexed in feeding order, so positions decrease with the index and the parts
    inside any stretch [x_lo, x_hi] of the belt form one index range (found by bisection).
    ``holder[i]`` is the robot that claimed or picked part i, or FREE; ``left_at[i]`` the
    time a claimed part is (or will be) gripped and leaves the belt.
    """

    def __init__(self, length: float, width: float, speed: float, grid: tuple[int, int]) -> None:
        self.length = length
        self.width = width
        self.speed = speed
        self.grid = grid
        self.cell = length / grid[0]
        self.tick = self.cell / speed  # time the belt needs to move one grid cell
        self.fed: list[float] = []
        self.y: list[float] = []
        self.kind: list[str] | None = None
        self.holder: list[int] = []
        self.left_at: list[float] = []  # grip time of a claimed part, inf while on the belt

    def load(self, fed: np.ndarray, y: np.ndarray, kind: list[str] | None = None) -> None:
        """Put the feeder's stream on the belt (each part appears at its fed time)."""
        self.fed = fed.tolist()
        self.y = y.tolist()
        self.kind = kind
        self.holder = [FREE] * len(self.fed)
        self.left_at = [math.inf] * len(self.fed)

    def __len__(self) -> int:
        return len(self.fed)

    def span(self, now: float, x_lo: float, x_hi: float) -> range:
        """Indices of the parts fed by ``now`` with x in [x_lo, x_hi] at ``now``."""
        v = self.speed
        lo = bisect_left(self.fed, now - x_hi / v)
        hi = bisect_right(self.fed, now - max(x_lo, 0.0) / v)
        return range(lo, hi)

    def next_entry(self, now: float, x: float) -> float:
        """Time until the next unclaimed part upstream of ``x`` reaches it (inf if none)."""
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
