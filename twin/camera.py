"""Observations: the belt as an image (the paper's 64 x 8 occupancy grid) and robot windows.

:class:`BeltCamera` draws a (C, H, W) uint8 image of the whole belt at the current epoch,
W cells along the belt (column 0 at the feeder) and H across (row 0 at the lower edge), from
the scenario's ``belt.grid`` (default 64 x 8). Channels, in order (``channels`` keeps the
first C of them):

====  =================  ==============================================================
 C    name               1 in a cell when
====  =================  ==============================================================
 0    parts              a part is on the belt there (fed, not yet gripped): the paper's
 1    claimed            a part there is claimed by a robot on its way to grip it
 2    busy               the column lies in the workspace of a robot that is not free now
                         (approaching, gripping, placing, in a NooP or down); whole column
====  =================  ==============================================================

A robot's window is the image's columns from the one holding its workspace start ``a_i``,
``w`` columns wide, where ``w`` is the widest workspace in cells (the same for every robot,
so agents can share one network); columns beyond the belt's end read 0.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

from pnp_twin.twin.belt import Belt
from pnp_twin.twin.scenario import Scenario

CHANNELS = ("parts", "claimed", "busy")


class BeltCamera:
    """Draws the image of one belt at a given time, with numpy.

    :meth:`attach` points it at a loaded :class:`~twin.belt.Belt`; :meth:`belt` and
    :meth:`window` draw it at time ``now``, with ``free`` the robots that are free then
    (the busy channel marks the others' workspaces).
    """

    def __init__(self, scenario: Scenario, channels: int = 1) -> None:
        if not 1 <= channels <= len(CHANNELS):
            raise ValueError(
                f"channels: {channels} is not allowed; give 1 to {len(CHANNELS)} "
                f"({', '.join(CHANNELS)})"
            )
        belt = scenario.belt
        self.channels = channels
        self.nx, self.ny = belt.grid
        self.length, self.width, self.speed = belt.length, belt.width, belt.speed
        cell = belt.length / self.nx
        spaces = scenario.robots.layout()
        self.starts = [int(math.floor(a / cell + 1e-9)) for a, _ in spaces]
        ends = [int(math.ceil(b / cell - 1e-9)) for _, b in spaces]
        self.window_width = max(e - s for s, e in zip(self.starts, ends, strict=True))
        self.spans = [(s, min(e, self.nx)) for s, e in zip(self.starts, ends, strict=True)]
        self.padded = max(self.nx, max(self.starts) + self.window_width)
        self.source: Belt | None = None
        self._rows: list[int] = []
        self._cache: np.ndarray | None = None
        self._cache_key: tuple[float, int] = (math.nan, -1)

    @property
    def shape(self) -> tuple[int, int, int]:
        """Shape of the whole-belt image (C, H, W)."""
        return (self.channels, self.ny, self.nx)

    @property
    def window_shape(self) -> tuple[int, int, int]:
        """Shape of a robot's window (C, H, w)."""
        return (self.channels, self.ny, self.window_width)

    def attach(self, belt: Belt) -> None:
        """Point the camera at a belt with its stream loaded (precomputes each part's row)."""
        self.source = belt
        rows = (np.asarray(belt.y, dtype=np.float64) * (self.ny / self.width)).astype(np.intp)
        self._rows = (np.minimum(rows, self.ny - 1) * self.padded).tolist()
        self._cache = None
        self._cache_key = (math.nan, -1)

    def _draw(self, now: float, free: Collection[int]) -> np.ndarray:
        """The padded image (C, H, padded W) at ``now``."""
        belt = self.source
        assert belt is not None, "BeltCamera.attach(belt) first"
        # About 30 parts lie on a paper_baseline belt: a plain loop into a bytearray beats
        # numpy's per-call overheads here.
        c, ny, width = self.channels, self.ny, self.padded
        plane = ny * width
        buf = bytearray(c * plane)
        on = belt.on_belt(now)
        if len(on):
            fed, left_at, holder, rows = belt.fed, belt.left_at, belt.holder, self._rows
            v, scale, last = self.speed, self.nx / self.length, self.nx - 1
            claimed = c > 1
            for i in on:
                if left_at[i] > now:  # not gripped yet
                    col = int(v * (now - fed[i]) * scale)  # as Belt.image rounds
                    flat = rows[i] + (col if col < last else last)
                    buf[flat] = 1
                    if claimed and holder[i] >= 0:
                        buf[plane + flat] = 1
        out = np.frombuffer(buf, dtype=np.uint8).reshape(c, ny, width)
        if c > 2:
            for robot, (s, e) in enumerate(self.spans):
                if robot not in free:
                    out[2, :, s:e] = 1
        return out

    def belt(self, now: float, free: Collection[int] = ()) -> np.ndarray:
        """The whole belt at ``now``, (C, H, W) uint8 (a fresh array on every call)."""
        image = self._draw(now, free)
        return image if self.padded == self.nx else image[:, :, : self.nx].copy()

    def window(
        self, robot: int, now: float, free: Collection[int] = (), epoch: int = 0
    ) -> np.ndarray:
        """Robot ``robot``'s (0-based) workspace window at ``now``, (C, H, w) uint8 (a fresh
        array). The image is drawn once per (``now``, ``epoch``) and shared by the windows
        of that epoch: give a new ``epoch`` whenever claims may have changed."""
        key = (now, epoch)
        if self._cache is None or key != self._cache_key:
            self._cache, self._cache_key = self._draw(now, free), key
        s = self.starts[robot]
        return self._cache[:, :, s : s + self.window_width].copy()
