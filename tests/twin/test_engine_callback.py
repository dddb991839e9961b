"""Python policies on the fast engine: the kernel stops at their decisions, asks them, and
the run is the SimPy twin's, event for event (the learned HDQN included)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from pnp_twin.policies import RuleChoosingPolicy, make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.scenario import Scenario

SCHEMES = ("t_continue", "t_all", "t_any")
MODELS = "models/paper_baseline__"


def same_runs(sc: Scenario, make: Any, seed: int = 5) -> tuple[Any, Any]:
    a = simulate(sc, make(), seed=seed, engine="simpy")
    b = simulate(sc, make(), seed=seed, engine="auto")
    assert b.meta["engine"] == "fast"
    for table in ("parts", "spans", "decisions"):
        pd.testing.assert_frame_equal(getattr(a, table), getattr(b, table), check_exact=True)
    assert repr(a.kpis) == repr(b.kpis)
    return a, b


class _Chooser(RuleChoosingPolicy):
    """Chooses by time and draws on the policy stream (SIRO), so streams must match too."""

    name = "py-chooser"

    def select_rule(self, decision: Decision) -> str:
        return ("SD", "SIRO", "FIFO")[int(decision.time) % 3]


class _Unnamed:
    """No last_rule: picks are counted under "?"; a second-to-last choice when it can."""

    name = "unnamed"

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.rng = rng

    def choose(self, decision: Decision) -> int:
        return max(0, len(decision) - 2)


class _Named(_Unnamed):
    """A rule name the engine does not know ("mine")."""

    last_rule = "mine"


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("policy", [_Chooser, _Unnamed, _Named])
def test_python_policies_run_identically(policy: type, scheme: str) -> None:
    sc = load_scenario("breakdowns", {"duration": 40.0, "warmup": 5.0, "termination": scheme})
    a, _ = same_runs(sc, policy)
    rules = set(a.decisions["rule"])
    assert {"?"} <= rules if policy is _Unnamed else True
    assert "mine" in rules if policy is _Named else True


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("model", ["async_rollout", "single"])
def test_the_learned_hdqn_runs_identically(model: str, scheme: str) -> None:
    pytest.importorskip("torch")
    sc = load_scenario("paper_baseline", {"duration": 30.0, "warmup": 5.0, "termination": scheme})
    a, _ = same_runs(sc, lambda: make_policy(f"hdqn:{MODELS}{model}", sc.robots.count))
    assert a.kpis["parts_picked"] > 0


def test_a_bad_answer_is_named() -> None:
    class Bad(_Unnamed):
        def choose(self, decision: Decision) -> int:
            return len(decision)

    sc = load_scenario("two_robot", {"duration": 10.0, "warmup": 1.0})
    with pytest.raises(IndexError, match="chose candidate"):
        simulate(sc, Bad(), engine="fast")


def test_hold_mode_pauses_at_every_epoch_and_resumes_on_release() -> None:
    """Under t_continue with hold every free robot is an epoch of one; releasing them with
    the rule mix's codes gives the mix's run."""
    sc = load_scenario("two_robot", {"duration": 30.0, "warmup": 1.0})
    held = FastLine(sc, rules=["SPT"], hold=True)
    held.start(*held._rooms())
    epochs = 0
    while (status := held.advance(held.end_at)) == 5:  # layout.ST_EPOCH
        assert len(held.pending()) >= 1
        held.release()
        epochs += 1
    assert status == 0 and held.finish() == 0
    straight = FastLine(sc, rules=["SPT"])
    straight.run()
    np.testing.assert_array_equal(held.rec_f, straight.rec_f)
    np.testing.assert_array_equal(held.rec_i, straight.rec_i)
    assert epochs > held.counts.sum() / 2
