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

    python bench/bench_policy_decision.py --students [--duration 120] [--rounds 3]

The students against their teacher, side by side in this one process: each round runs the
lookahead controller (its defaults, ``policy_stats``' CPU per decision) and then each student
(``process_time`` around ``choose``) on the same seed (100 + round; one uncounted run of each
first loads the compiled code), and prints each one's CPU us per decision (median round),
the **ratio** of the student's to the lookahead's (target <= 0.1), and the CPU model (as
``lscpu`` names it).
"""

from __future__ import annotations

import argparse
import platform
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


STUDENTS = ("paper_baseline__student", "student_general", "student_any")
RATIO_TARGET = 0.1


def cpu_model() -> str:
    """The CPU's model name, as ``lscpu`` shows it (``/proc/cpuinfo``)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def cpu_us(spec: str, scenario, seed: int) -> float:  # type: ignore[no-untyped-def]
    """CPU us per decision of one run: the lookahead's own stats, a student's ``choose``."""
    from pnp_twin.policies.registry import make_policy

    policy = make_policy(spec)
    stats = getattr(policy, "stats", None)
    spent = [0.0, 0]
    if stats is None:
        inner = policy.choose

        def timed(decision):  # type: ignore[no-untyped-def]
            t0 = time.process_time()
            k = inner(decision)
            spent[0] += time.process_time() - t0
            spent[1] += 1
            return k

        policy.choose = timed  # type: ignore[method-assign]
    simulate(scenario, policy, seed=seed, engine="fast")
    if stats is not None:
        return 1000.0 * float(stats()["cpu_ms_per_decision"])
    return 1e6 * spent[0] / max(spent[1], 1)


def students(duration: float, rounds: int) -> None:
    import torch

    torch.set_num_threads(1)
    scenario = with_overrides(
        load_scenario("paper_baseline"), {"duration": duration, "warmup": 10.0}
    )
    specs = ["lookahead", *(f"hdqn:{m}" for m in STUDENTS)]
    short = with_overrides(scenario, {"duration": 30.0})
    for spec in specs:  # uncounted: loads the compiled code
        cpu_us(spec, short, 99)
    got: dict[str, list[float]] = {s: [] for s in specs}
    for r in range(rounds):
        for spec in specs:
            got[spec].append(cpu_us(spec, scenario, 100 + r))
    look = statistics.median(got["lookahead"])
    print(f"CPU: {cpu_model()}; paper_baseline, {duration:g} s simulated, {rounds} rounds")
    print(f"{'lookahead (K=16, H=1)':32s} {look:8.1f} us CPU per decision")
    for spec in specs[1:]:
        us = statistics.median(got[spec])
        ratio = us / look
        verdict = "meets" if ratio <= RATIO_TARGET else "misses"
        print(
            f"{spec:32s} {us:8.1f} us CPU per decision; ratio to the lookahead {ratio:.3f} "
            f"(target <= {RATIO_TARGET:g}: {verdict})"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["async", "sync", "single"])
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--students", action="store_true", help="students vs the lookahead's CPU")
    args = ap.parse_args()
    if args.students:
        students(args.duration, args.rounds)
        return
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
