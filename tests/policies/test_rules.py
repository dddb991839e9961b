"""Each dispatching rule chooses what MODEL.md says, on a hand-crafted decision."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pnp_twin.policies import RULES, make_policy
from pnp_twin.policies.base import RuleMix
from pnp_twin.policies.registry import PolicyError
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.geometry import intercept_time, move_time

SPEC = RobotSpec(
    index=0,
    count=2,
    workspace=(0.25, 1.0),
    bin=(0.55, 0.65),
    arm_speed=3.0,
    acceleration=0.0,
    pick_time=0.12,
    place_time=0.12,
    belt_speed=0.8,
    belt_width=0.4,
)
TOOL = (0.55, 0.65)  # the robot just placed: its tool is at its bin

# Five candidates, furthest downstream first (the order they entered the workspace).
# index:      0     1     2     3     4
XS = [0.78, 0.68, 0.55, 0.45, 0.34]
YS = [0.20, 0.39, 0.03, 0.36, 0.25]
# 0 = FIFO (first in), 4 = LIFO (last in), 1 = SD (nearest the upper edge, y = 0.39),
# 2 = LD (nearest the lower edge, y = 0.03), 3 = SPT (it moves towards the bin: the shortest
# full cycle, about 0.434 s against 0.468 s for the SD part).
EXPECTED = {"FIFO": 0, "LIFO": 4, "SD": 1, "LD": 2, "SPT": 3}


def intercept(x: float, y: float, spec: RobotSpec = SPEC, tool=TOOL) -> float:
    """Interception time from the tool, solving the quadratic of MODEL.md."""
    vb, vr = spec.belt_speed, spec.arm_speed
    dx, dy = x - tool[0], y - tool[1]
    a, b, c = vr * vr - vb * vb, -2 * dx * vb, -(dx * dx + dy * dy)
    return (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)


def make_decision(spec: RobotSpec = SPEC, xs=XS, ys=YS, tool=TOOL) -> Decision:
    if spec.acceleration > 0:
        v, vr, acc = spec.belt_speed, spec.arm_speed, spec.acceleration
        times = [
            intercept_time(x - tool[0], y - tool[1], v, vr, acc)
            for x, y in zip(xs, ys, strict=True)
        ]
    else:
        times = [intercept(x, y, spec, tool) for x, y in zip(xs, ys, strict=True)]
    return Decision(spec, 12.5, tool, list(range(100, 100 + len(xs))), list(xs), list(ys), times)


def full_cycle(d: Decision, k: int) -> float:
    s = d.spec
    t = d.times[k]
    xi = d.xs[k] + s.belt_speed * t
    return t + s.pick_time + math.dist(s.bin, (xi, d.ys[k])) / s.arm_speed + s.place_time


def test_crafted_decision_is_realistic() -> None:
    d = make_decision()
    a, b = SPEC.workspace
    for x, t in zip(d.xs, d.times, strict=True):
        assert a <= x + SPEC.belt_speed * t <= b  # every candidate is interceptable inside


@pytest.mark.parametrize("rule", sorted(EXPECTED))
def test_rule_chooses_what_model_md_says(rule: str) -> None:
    d = make_decision()
    assert RULES[rule](d, np.random.default_rng(0)) == EXPECTED[rule]


def test_the_crafted_answers_follow_from_the_definitions() -> None:
    d = make_decision()
    assert EXPECTED["SD"] == int(np.argmax(YS))
    assert EXPECTED["LD"] == int(np.argmin(YS))
    cycles = [full_cycle(d, k) for k in range(len(d))]
    assert EXPECTED["SPT"] == int(np.argmin(cycles))
    assert cycles[3] == pytest.approx(0.4339, abs=1e-3)
    # five rules, five different answers: the decision tells the rules apart
    assert len(set(EXPECTED.values())) == 5


def test_spt_accounts_for_acceleration() -> None:
    # With a weak acceleration limit (2 m/s^2) a full cycle uses trapezoidal move times,
    # and that reverses the ranking of these two parts.
    spec = RobotSpec(0, 1, (0.0, 2.0), (0.5, 0.65), 3.0, 2.0, 0.1, 0.1, 0.8, 0.4)
    xs, ys, tool = [0.55, 0.03], [0.30, 0.22], (0.5, 0.65)
    d = make_decision(spec, xs=xs, ys=ys, tool=tool)
    cyc = []
    for x, y, t in zip(d.xs, d.ys, d.times, strict=True):
        xi = x + 0.8 * t
        cyc.append(t + 0.2 + move_time(math.dist(spec.bin, (xi, y)), 3.0, 2.0))
    assert int(np.argmin(cyc)) == 1
    assert RULES["SPT"](d, np.random.default_rng(0)) == 1
    plain = RobotSpec(0, 1, (0.0, 2.0), (0.5, 0.65), 3.0, 0.0, 0.1, 0.1, 0.8, 0.4)
    assert (
        RULES["SPT"](make_decision(plain, xs=xs, ys=ys, tool=tool), np.random.default_rng(0)) == 0
    )


def test_single_candidate_is_always_chosen() -> None:
    d = make_decision(xs=[0.5], ys=[0.2])
    for rule in RULES.values():
        assert rule(d, np.random.default_rng(3)) == 0


def test_siro_is_uniform_ish() -> None:
    d = make_decision()
    rng = np.random.default_rng(7)
    n = 5000
    counts = np.bincount([RULES["SIRO"](d, rng) for _ in range(n)], minlength=5)
    assert counts.sum() == n
    # each of 5 candidates expects 1000; sd ~ 28, so 850..1150 is a > 5-sigma band
    assert (counts > 850).all() and (counts < 1150).all(), counts


def test_siro_is_reproducible_with_the_same_seed() -> None:
    d = make_decision()

    def draw(seed: int) -> list[int]:
        rng = np.random.default_rng(seed)
        return [RULES["SIRO"](d, rng) for _ in range(50)]

    assert draw(11) == draw(11)
    assert draw(11) != draw(12)


def test_policy_records_the_rule_it_used_and_mixes_are_per_robot() -> None:
    mix = make_policy("spt,FIFO")
    assert isinstance(mix, RuleMix)
    mix.reset(
        [SPEC, RobotSpec(1, 2, (1.0, 1.5), (1.25, 0.65), 3, 0, 0.1, 0.1, 0.8, 0.4)],
        np.random.default_rng(0),
    )
    d0 = make_decision()
    assert mix.choose(d0) == EXPECTED["SPT"] and mix.last_rule == "SPT"
    spec1 = RobotSpec(1, 2, (0.25, 1.0), (0.55, 0.65), 3.0, 0.0, 0.12, 0.12, 0.8, 0.4)
    d1 = make_decision(spec1)
    assert mix.choose(d1) == EXPECTED["FIFO"] and mix.last_rule == "FIFO"


def test_one_rule_applies_to_every_robot_and_bad_names_are_refused() -> None:
    sd = make_policy("sd")
    specs = [SPEC, RobotSpec(1, 2, (0.25, 1.0), (0.55, 0.65), 3.0, 0.0, 0.12, 0.12, 0.8, 0.4)]
    sd.reset(specs, np.random.default_rng(0))
    for spec in specs:
        d = make_decision(spec)
        assert sd.choose(d) == EXPECTED["SD"] and sd.last_rule == "SD"
    with pytest.raises(PolicyError, match="'XYZ' is not a rule"):
        make_policy("xyz")
    with pytest.raises(PolicyError, match="names 3 rules for 2 robots"):
        make_policy("SD,SD,LD", n_robots=2)
