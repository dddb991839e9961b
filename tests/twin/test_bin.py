"""twin.bin: place timing, box capacity, and the box change as a process."""

from __future__ import annotations

import simpy

from pnp_twin.twin.bin import Bin


def test_an_unlimited_bin_never_blocks():
    env = simpy.Environment()
    bin_ = Bin(env, (1.0, 0.6), capacity=0, change_time=5.0)
    assert bin_.place(1.0, 0.25) == (0.0, 1.25)
    assert bin_.place(1.1, 0.25) == (0.0, 1.35)
    assert bin_.boxes == 0 and bin_.ready_at == 0.0


def test_a_full_box_is_changed_and_blocks_the_next_place_until_it_is_done():
    env = simpy.Environment()
    bin_ = Bin(env, (1.0, 0.6), capacity=2, change_time=3.0)
    assert bin_.place(0.0, 0.25) == (0.0, 0.25)
    assert bin_.place(1.0, 0.25) == (0.0, 1.25)  # fills the box: the change runs to 4.25
    assert bin_.ready_at == 1.25 + 3.0 and bin_.count == 0
    assert bin_.place(2.0, 0.25) == (4.25 - 2.0, 4.5)  # blocked 2.25 s, placed at 4.5
    assert bin_.place(5.0, 0.25) == (0.0, 5.25)  # the second box is full again
    assert bin_.ready_at == 5.25 + 3.0


def test_the_box_change_process_takes_the_box_away_when_the_last_place_ends():
    env = simpy.Environment()
    bin_ = Bin(env, (1.0, 0.6), capacity=1, change_time=2.0)
    states: list[tuple[float, int, bool]] = []

    def watching() -> simpy.events.ProcessGenerator:
        for t in (0.5, 1.5, 3.0, 3.5):
            yield env.timeout(t - env.now)
            states.append((env.now, bin_.boxes, bin_.changing))

    env.process(watching())
    bin_.place(0.0, 1.0)  # placed at 1.0, then changed until 3.0
    env.run()
    assert states == [(0.5, 0, False), (1.5, 1, True), (3.0, 1, False), (3.5, 1, False)]
