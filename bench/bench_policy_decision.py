"""Benchmark: microseconds per learned-policy decision, torch's forward vs numpy's.

    python bench/bench_policy_decision.py [--models async sync single] [--duration 120]
                                          [--rounds 3]

Runs ``paper_baseline`` (``--duration`` simulated seconds, the fast engine) with the shipped
HDQN policy of each model, once with decisions through torch (``numpy_forward=False``) and
once through the numpy forward pass, interleaved round by round; a decision is the whole
``HDQNPolicy.choose`` (the camera's observation, the network, the rule), timed with
``perf_counter`` around each call. Prints us per decision (the median round) of both, the
ratio, the 100 us target beside it, the share of decisions numpy handed to torch (near
ties; all of them for a model numpy does not run, e.g. ``single``'s 250,000 weights), and
checks that both runs made the same decisions (the parts table, rule by rule).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import pandas as pd

from pnp_twin.policies.hdqn.policy import HDQNPolicy
from pnp_twin.twin import load_scenario, with_overrides
from pnp_twin.twin.run import simulate

TARGET_US = 100.0
MODELS = Path(__file__).resolve().parents[1] / "models"


class Timed(HDQNPolicy):
    """HDQNPolicy with a stopwatch around each decision."""

    spent = 0.0
    calls = 0

    def choose(self, decision):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        out = super().choose(decision)
        self.spent += time.perf_counter() - t0
        self.calls += 1
        return out


def run(model: str, numpy_forward: bool, scenario) -> tuple[float, int, int, pd.DataFrame]:  # type: ignore[no-untyped-def]
    base = HDQNPolicy.load(MODELS / model)
    policy = Timed(base.agent, base.meta, numpy_forward=numpy_forward)
    result = simulate(scenario, policy, engine="fast")
    parts = result.parts[["part", "robot", "rule", "picked_at"]]
    return policy.spent / policy.calls * 1e6, policy.torch_decisions, policy.calls, parts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["async", "sync", "single"])
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    scenario = with_overrides(
        load_scenario("paper_baseline"), {"duration": args.duration, "warmup": 10.0}
    )
    simulate(scenario, HDQNPolicy.load(MODELS / "paper_baseline__async"), engine="fast")  # warm
    print(f"paper_baseline, {args.duration:g} s simulated, fast engine; us per decision")
    for name in args.models:
        model = f"paper_baseline__{name}"
        torch_us, numpy_us, handed, decisions = [], [], 0, 0
        for _ in range(args.rounds):
            t_us, _, _, t_parts = run(model, False, scenario)
            n_us, n_torch, n_calls, n_parts = run(model, True, scenario)
            pd.testing.assert_frame_equal(n_parts, t_parts)  # the same decisions
            torch_us.append(t_us)
            numpy_us.append(n_us)
            handed += n_torch
            decisions += n_calls
        t, n = statistics.median(torch_us), statistics.median(numpy_us)
        verdict = "meets" if n <= TARGET_US else "misses"
        print(
            f"{model:32s} torch {t:6.1f}  numpy {n:6.1f}  ratio {n / t:.2f}  "
            f"(target <= {TARGET_US:g} us: {verdict}); near ties handed to torch: "
            f"{handed / max(decisions, 1):.1%}; identical decisions"
        )


if __name__ == "__main__":
    main()
