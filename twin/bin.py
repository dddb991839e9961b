"""The packaging bin beside each robot: a place target, a capacity and box changes."""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import simpy


class Bin:
    """A box that takes ``capacity`` parts (0 = unlimited), then is changed.

    A place is booked when the robot sets off towards the bin (:meth:`place`), so it needs no
    event of its own: the robot learns at once how long a box change will block it. The box
    change itself is the process :meth:`changing_box`, started when a place fills the box:
    it waits for that place to end, takes the full box away (:attr:`boxes`) and is done
    ``change_time`` seconds later (:attr:`ready_at`, :attr:`changing`).
    """

    def __init__(
        self,
        env: simpy.Environment,
        position: tuple[float, float],
        capacity: int,
        change_time: float,
    ) -> None:
        self.env = env
        self.position = position
        self.capacity = capacity
        self.change_time = change_time
        self.count = 0  # parts booked into the current box
        self.boxes = 0  # full boxes taken away
        self.ready_at = 0.0  # end of the latest box change
        self.changing = False  # a box change is under way

    def place(self, arrive_at: float, place_time: float) -> tuple[float, float]:
        """Book a part arriving at ``arrive_at``: (time blocked by a box change, time placed).

        A place that fills the box starts its change (``change_time`` from the place's end).
        """
        start = max(arrive_at, self.ready_at)
        done = start + place_time
        self.count += 1
        if self.capacity and self.count >= self.capacity:
            self.count = 0
            self.ready_at = done + self.change_time
            self.env.process(self.changing_box(done))
        return start - arrive_at, done

    def changing_box(self, full_at: float) -> Generator[simpy.Event, Any, None]:
        """The box change: from the end of the place that filled the box, ``change_time`` s."""
        env = self.env
        if full_at > env.now:
            yield env.timeout(full_at - env.now)
        self.boxes += 1
        self.changing = True
        yield env.timeout(self.ready_at - env.now)
        self.changing = False
