"""Invariants over random small lines (hypothesis): conservation of parts and friends.

For any line (1-5 robots, speeds, rates, workspaces, schemes, breakdowns, bins, arm ramps,
any rule or mix): every part fed has one outcome (presented = picked + missed), no part is
picked twice or offered after it was taken, picks happen inside the picking robot's
workspace, placed_at > picked_at >= decided_at with the exact transfer time, a robot's
cycles and waits never overlap, and no robot gets stuck. Most checks live in
``conftest.check_run``.
"""

from __future__ import annotations

from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pnp_twin.policies import RULES, make_policy

RULE_NAMES = sorted(RULES)

# A line hypothesis found that freezes the simulated clock (no acceleration limit involved).
FROZEN_LINE: dict[str, Any] = {
    "belt.speed": 0.6055497911946746,
    "belt.length": 0.4887873017385138,
    "belt.width": 0.39191207037604303,
    "feeder.arrival": "normal",
    "feeder.rate": 7.566006294165903,
    "feeder.lateral": "uniform",
    "robots.count": 2,
    "robots.first_workspace_start": 0.0887873017385138,
    "robots.workspace_length": 0.15,
    "robots.workspace_gap": 0.1,
    "robots.arm_speed": 1.211105637887261,
    "robots.pick_time": 0.15252163743229294,
    "robots.place_time": 0.0887873017385138,
    "robots.bin_offset": [0.2, 0.2991057939498979],
    "bins.capacity": 3,
    "bins.change_time": 0.5,
    "duration": 12.0,
    "warmup": 2.0,
    "seed": 2,
}


@st.composite
def lines(draw: st.DrawFn) -> tuple[dict[str, Any], str]:
    """A random small line as scenario overrides, and a policy spec."""
    n = draw(st.integers(1, 5))
    v_b = draw(st.floats(0.3, 1.2))
    first = draw(st.floats(0.0, 0.5))
    length = draw(st.floats(0.15, 0.6))
    gap = draw(st.sampled_from([0.0, 0.0, 0.1, 0.3]))
    end = first + n * length + (n - 1) * gap
    line: dict[str, Any] = {
        "belt.speed": v_b,
        "belt.length": end + draw(st.floats(0.0, 0.5)),
        "belt.width": draw(st.floats(0.2, 0.6)),
        "belt.grid": [draw(st.sampled_from([16, 64])), 8],
        "feeder.arrival": draw(st.sampled_from(["poisson", "normal", "fixed"])),
        "feeder.rate": draw(st.floats(1.0, 15.0)),
        "feeder.lateral": draw(st.sampled_from(["normal", "uniform"])),
        "robots.count": n,
        "robots.first_workspace_start": first,
        "robots.workspace_length": length,
        "robots.workspace_gap": gap,
        "robots.arm_speed": v_b * draw(st.floats(1.3, 6.0)),
        "robots.pick_time": draw(st.floats(0.02, 0.3)),
        "robots.place_time": draw(st.floats(0.02, 0.3)),
        "robots.acceleration": draw(st.sampled_from([0.0, 0.0, 5.0, 30.0])),
        "robots.bin_offset": [draw(st.floats(-0.2, 0.2)), draw(st.floats(0.05, 0.4))],
        "termination": draw(st.sampled_from(["t_continue", "t_all", "t_any"])),
        "bins.capacity": draw(st.sampled_from([0, 0, 3, 8])),
        "bins.change_time": draw(st.sampled_from([0.0, 0.5, 2.0])),
        "duration": 12.0,
        "warmup": 2.0,
        "seed": draw(st.integers(0, 10_000)),
    }
    if draw(st.booleans()):  # breakdowns on
        line["robots.mtbf"] = draw(st.floats(1.0, 8.0))
        line["robots.mttr"] = draw(st.floats(0.2, 3.0))
        line["robots.failure_distribution"] = draw(st.sampled_from(["exponential", "fixed"]))
    if n > 1 and draw(st.booleans()):  # one robot differs from the others
        line["robots.overrides"] = [
            {"robot": draw(st.integers(1, n)), "arm_speed": v_b * 2.5, "pick_time": 0.05}
        ]
    if draw(st.booleans()):
        policy = draw(st.sampled_from(RULE_NAMES))
    else:
        policy = ",".join(draw(st.lists(st.sampled_from(RULE_NAMES), min_size=n, max_size=n)))
    return line, policy


@settings(
    max_examples=35,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(case=lines())
def test_parts_are_conserved_on_any_line(
    case: tuple[dict[str, Any], str], make_scenario, logging_policy, check_invariants, guarded
) -> None:
    overrides, spec = case
    scenario = make_scenario(overrides)
    policy = logging_policy(make_policy(spec, n_robots=scenario.robots.count))
    result = guarded(scenario, policy)  # a frozen clock raises conftest.Livelock
    check_invariants(result, policy.choices)
    if scenario.feeder.arrival == "fixed":  # one part every 1/rate seconds, from t = 0
        assert abs(len(result.parts) - scenario.duration * scenario.feeder.rate) <= 1
    if scenario.robots.mtbf == 0:
        assert not (result.spans["state"] == "down").any()
    if scenario.termination != "t_any":
        assert not (result.spans["state"] == "interrupted").any()
    if scenario.termination == "t_continue":
        assert not (result.spans["state"] == "wait").any()
    # no robot gets stuck (say, waiting for an epoch that never opens): each one's recorded
    # activity goes on past the end of the feed, into the drain
    picked = result.parts[result.parts["outcome"] == "picked"]
    for r in range(scenario.robots.count):
        ends = result.spans.loc[result.spans["robot"] == r + 1, "end"].tolist()
        ends += picked.loc[picked["robot"] == r + 1, "placed_at"].tolist()
        assert max(ends, default=0.0) > scenario.duration, f"robot {r} stopped"


def test_noop_never_freezes_the_clock(make_scenario, logging_policy, check_invariants, guarded):
    scenario = make_scenario(FROZEN_LINE, policy="LD")
    policy = logging_policy(make_policy("LD"))
    # before the fix of Belt.next_entry this froze at t = 1.7578 s (a NooP of 0 s, forever)
    result = guarded(scenario, policy)
    check_invariants(result, policy.choices)
    assert result.kpis["parts_picked"] > 0
