"""The packaging bin beside each robot: a place target, a capacity and box changes."""

from __future__ import annotations


class Bin:
    """A box that takes ``capacity`` parts (0 = unlimited), then is changed.

    During a box change (``change_time`` seconds) the robot cannot place. Timing is computed
    when the robot arrives, so a place needs no extra event.
    """

    def __init__(self, position: tuple[float, float], capacity: int, change_time: float) -> None:
        self.position = position
        self.capacity = capacity
        self.change_time = change_time
        self.count = 0  # parts in the current box
        self.boxes = 0  # completed boxes
        self.ready_at = 0.0  # end of the current box change

    def place(self, arrive_at: float, place_time: float) -> tuple[float, float]:
        """A part arrives at ``arrive_at``: (time blocked by a box change, time placed)."""
        start = max(arrive_at, self.ready_at)
        done = start + place_time
        self.count += 1
        if self.capacity and self.count >= self.capacity:
            self.count = 0
            self.boxes += 1
            self.ready_at = done + self.change_time
        return start - arrive_at, done
