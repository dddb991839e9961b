"""twin.belt: what is on the belt when, claims, the NooP wait, exits and the feeder's puts."""

from __future__ import annotations

import math

import numpy as np
import simpy

from pnp_twin.twin.belt import FREE, SWEEP, Belt
from pnp_twin.twin.feeder import Feeder
from pnp_twin.twin.records import Recorder
from pnp_twin.twin.scenario import FeederConfig

# A 2 m belt at 0.5 m/s, 20 x 4 cells of 0.1 m; the last workspace ends at 1.5 m (3 s).
FED = [0.0, 0.5, 1.0, 1.0, 2.5]
YS = [0.05, 0.15, 0.25, 0.35, 0.05]


def loaded(arrived: int = len(FED)) -> Belt:
    belt = Belt(2.0, 0.4, 0.5, (20, 4), end=1.5)
    belt.load(np.array(FED), np.array(YS))
    belt.put(arrived)
    return belt


def test_a_part_is_seen_only_once_the_feeder_has_put_it():
    belt = loaded(arrived=0)
    assert list(belt.span(1.0, 0.0, 2.0)) == []
    belt.put(2)
    assert list(belt.span(1.0, 0.0, 2.0)) == [0, 1]
    belt.put(4)  # parts 2 and 3 arrive together at t = 1
    assert list(belt.span(1.0, 0.0, 2.0)) == [0, 1, 2, 3]


def test_span_is_the_index_range_inside_a_stretch():
    belt = loaded()
    # at t = 2: parts 0..3 are at x = 1.0, 0.75, 0.5, 0.5; part 4 is not fed yet
    assert list(belt.span(2.0, 0.6, 1.0)) == [0, 1]
    assert list(belt.span(2.0, 0.5, 0.5)) == [2, 3]
    assert list(belt.span(2.0, -1.0, 0.4)) == []


def test_next_entry_skips_claimed_parts_and_counts_parts_still_to_come():
    belt = loaded(arrived=2)
    assert belt.next_entry(0.2, 0.5) == 1.0 - 0.2  # part 0 reaches x = 0.5 at t = 1
    belt.claim(0, robot=1, grip_at=0.9)
    assert belt.next_entry(0.2, 0.5) == 1.5 - 0.2  # then part 1, at t = 1.5
    # at t = 3 every fed part is past x = 0.5: the next one is part 4, not yet fed
    assert belt.next_entry(3.0, 0.5) == 2.5 + 1.0 - 3.0
    assert belt.next_entry(4.0, 0.5) == math.inf


def test_claim_books_the_grip_and_release_frees_the_part():
    belt = loaded()
    belt.claim(1, robot=2, grip_at=1.25)
    assert belt.holder[1] == 2 and belt.left_at[1] == 1.25
    assert belt.image(1.2, free_only=True).sum() == 3  # parts 0, 2, 3: part 1 is claimed
    assert belt.image(1.2).sum() == 4  # claimed, not gripped yet: still on the belt
    assert belt.image(1.25).sum() == 3  # gripped at 1.25
    belt.release(1)
    assert belt.holder[1] == FREE and belt.left_at[1] == math.inf
    assert belt.image(1.25).sum() == 4


def test_image_cells_follow_the_analytic_positions():
    belt = loaded()
    image = belt.image(2.0)  # x = 1.0, 0.75, 0.5, 0.5 -> columns 10, 7, 5, 5
    rows, cols = np.nonzero(image)
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [
        (0, 10),
        (1, 7),
        (2, 5),
        (3, 5),
    ]


def test_exits_and_passed_count_parts_past_the_last_workspace():
    belt = loaded()
    assert belt.exit_at(1) == 0.5 + 1.5 / 0.5
    assert belt.passed(2.99) == 0 and belt.passed(3.0) == 1 and belt.passed(4.0) == 4


def test_conveying_records_the_free_parts_that_pass_the_end_with_their_exit_time():
    env = simpy.Environment()
    belt = loaded()
    rec = Recorder(len(FED))
    belt.claim(2, robot=0, grip_at=2.0)  # part 2 is gripped before its exit at t = 4
    env.process(belt.conveying(env, rec))
    assert SWEEP == 5.0
    env.run(until=4.9)  # parts 0, 1, 3 are past the end, but the first sweep is at t = 5
    assert all(math.isnan(t) for t in rec.missed_at)
    env.run(until=5.1)
    assert rec.missed_at[:2] == [3.0, 3.5] and rec.missed_at[3] == 4.0
    assert math.isnan(rec.missed_at[2]) and math.isnan(rec.missed_at[4])  # 4 exits at 5.5
    env.run()
    assert env.now == 2 * SWEEP and rec.missed_at[4] == 5.5  # the last sweep ends it
    assert math.isnan(rec.missed_at[2])


def test_the_feeder_puts_each_part_at_its_arrival_before_anything_else_then():
    env = simpy.Environment()
    belt = loaded(arrived=0)
    feeder = Feeder(FeederConfig(), 0.4, np.random.default_rng(0), np.random.default_rng(1))
    seen: list[tuple[float, int]] = []

    def looking() -> simpy.events.ProcessGenerator:
        for t in (0.0, 0.5, 0.7, 1.0, 2.5):
            yield env.timeout(t - env.now)
            seen.append((env.now, len(belt.span(env.now, 0.0, 2.0))))

    env.process(looking())  # started first: at a shared instant only the URGENT put wins
    env.process(feeder.feeding(env, belt))
    env.run()
    assert seen == [(0.0, 1), (0.5, 2), (0.7, 2), (1.0, 4), (2.5, 5)]
    assert belt.arrived == len(FED)


def test_the_feeder_wakes_at_the_arrival_time_exactly_even_where_now_plus_gap_misses_it():
    cases = [(0.1, 0.30000000000000004), (2.5, 7.3), (9.998959634316407e-05, 98.13947175140338)]
    now, at = cases[-1]
    sums = {now + (at - now + k * math.ulp(at)) for k in range(-3, 4)}
    assert at not in sums  # ties to even: no delay from ``now`` lands on ``at``
    for now, at in cases:
        env = simpy.Environment(initial_time=now)
        belt = Belt(2.0, 0.4, 0.5, (20, 4), end=1.5)
        belt.load(np.array([at]), np.array([0.2]))
        feeder = Feeder(FeederConfig(), 0.4, np.random.default_rng(0), np.random.default_rng(1))
        env.process(feeder.feeding(env, belt))
        env.run()
        assert env.now == at and belt.arrived == 1
