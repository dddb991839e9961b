"""What a policy (and the record tables) may read of a fast run's belt, from its arrays.

The SimPy twin hands policies that look at the belt (``attach(belt)``: the learned HDQN's
camera, a Stable-Baselines3 model's) its :class:`twin.belt.Belt`. The fast engine hands them
a :class:`BeltView` over its state arrays instead: the same attributes and queries, read
only, always current (claims and releases write ``holder`` and ``left_at`` in place). At a
decision every part fed up to now is on the belt (the feeder's events come first at a shared
instant), so ``arrived`` is the number fed by now.
"""

from __future__ import annotations

import numpy as np

from pnp_twin.twin.geometry import exit_time


class BeltView:
    """A read-only :class:`twin.belt.Belt` over the fast engine's arrays."""

    def __init__(
        self,
        length: float,
        width: float,
        speed: float,
        grid: tuple[int, int],
        end: float,
        arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
        kind: list[str] | None,
        clock: np.ndarray,
    ) -> None:
        self.length, self.width, self.speed, self.grid, self.end = length, width, speed, grid, end
        self.cell = length / grid[0]
        self.tick = self.cell / speed
        self.fed, self.y, self.holder, self.left_at = arrays
        self.kind = kind
        self._clock = clock  # gf: gf[0] is the run's clock

    def __len__(self) -> int:
        return len(self.fed)

    @property
    def arrived(self) -> int:
        """Parts the feeder has put on the belt by now."""
        return int(np.searchsorted(self.fed, self._clock[0], "right"))

    def on_belt(self, now: float) -> range:
        """Indices that may be on the belt at ``now`` (as Belt.on_belt)."""
        lo = int(np.searchsorted(self.fed, now - self.length / self.speed, "left"))
        return range(lo, min(int(np.searchsorted(self.fed, now, "right")), self.arrived))

    def span(self, now: float, x_lo: float, x_hi: float) -> range:
        """Indices of the parts on the belt at ``now`` with x in [x_lo, x_hi]."""
        v = self.speed
        lo = int(np.searchsorted(self.fed, now - x_hi / v, "left"))
        hi = int(np.searchsorted(self.fed, now - (x_lo if x_lo > 0.0 else 0.0) / v, "right"))
        return range(lo, min(hi, self.arrived))

    def passed(self, now: float) -> int:
        """How many parts have passed the last workspace's end by now."""
        return int(np.searchsorted(self.fed, now - self.end / self.speed, "right"))

    def exit_at(self, part: int) -> float:
        """When ``part`` passes the end of the last workspace (picked or not)."""
        return exit_time(float(self.fed[part]), self.end, self.speed)
