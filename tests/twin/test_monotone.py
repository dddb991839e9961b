"""More robots, a faster arm or a slower feed never lower G by more than noise.

Common random numbers: for one seed every variant sees the same part stream (the feeder
has its own random streams; a slower Poisson feed is the same stream, stretched), so the
differences are the line's, not the sampling's. Steps are small on purpose (arm +0.25 m/s,
feed -1 part/s) so that the check is about noise, not about large effects.
"""

from __future__ import annotations

from functools import cache

import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate

NOISE = 1.5  # percentage points of G
CASES = [  # (termination, policy, seeds)
    ("t_continue", "SD", (0, 1, 2)),
    ("t_continue", "FIFO", (0, 1)),
    ("t_all", "SD", (0, 1)),
    ("t_any", "SIRO", (0, 1)),
]


@cache
def gripping_rate(
    make, scheme: str, policy: str, seed: int, count: int, arm: float, rate: float
) -> float:
    """G of one variant (cached: the base line recurs in every family)."""
    scenario = make(
        {
            "termination": scheme,
            "belt.length": 3.0,  # room for five workspaces
            "robots.count": count,
            "robots.arm_speed": arm,
            "feeder.rate": rate,
            "duration": 90.0,
            "warmup": 10.0,
            "seed": seed,
        }
    )
    return simulate(scenario, make_policy(policy)).kpis["gripping_rate"]


def assert_never_lower(gs: list[float], what: str) -> None:
    for lo, hi in zip(gs, gs[1:], strict=False):
        assert hi >= lo - NOISE, f"{what}: G went from {lo:.2f} to {hi:.2f} ({gs})"


@pytest.mark.parametrize(("scheme", "policy", "seeds"), CASES)
def test_more_robots_never_lower_g(make_scenario, scheme: str, policy: str, seeds) -> None:
    for seed in seeds:
        for rate in (10.0, 4.0):  # a heavy feed and one the line nearly clears
            gs = [
                gripping_rate(make_scenario, scheme, policy, seed, n, 3.0, rate)
                for n in (1, 2, 3, 4, 5)
            ]
            assert_never_lower(gs, f"robots 1..5, rate {rate}, seed {seed}")
            assert gs[-1] > gs[0]


@pytest.mark.parametrize(("scheme", "policy", "seeds"), CASES)
def test_a_faster_arm_never_lowers_g(make_scenario, scheme: str, policy: str, seeds) -> None:
    for seed in seeds:
        gs = [
            gripping_rate(make_scenario, scheme, policy, seed, 4, v, 10.0)
            for v in (3.0, 3.25, 3.5, 4.0)
        ]
        assert_never_lower(gs, f"arm 3..4 m/s, seed {seed}")
        assert gs[-1] > gs[0]


@pytest.mark.parametrize(("scheme", "policy", "seeds"), CASES)
def test_a_slower_feed_never_lowers_g(make_scenario, scheme: str, policy: str, seeds) -> None:
    for seed in seeds:
        gs = [
            gripping_rate(make_scenario, scheme, policy, seed, 4, 3.0, r)
            for r in (11.0, 10.0, 9.0, 8.0)
        ]
        assert_never_lower(gs, f"feed 11..8 parts/s, seed {seed}")
        assert gs[-1] > gs[0]
