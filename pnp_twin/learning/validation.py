"""Validation during training: the greedy policy against every single rule, paired by seed.

Both trainings (:mod:`pnp_twin.learning.train` and :mod:`pnp_twin.learning.rollout_train`)
write one row of :data:`VALIDATION_COLUMNS` per evaluation into ``eval.csv``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pnp_twin.policies.hdqn import TERMINATION
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Policy
from pnp_twin.twin.loader import with_overrides
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

VALIDATION_SEED_BASE = 500_000
"""Validation seeds are 500,000 + i (training episodes use >= 1,000,000; evaluate 0..n-1)."""

VALIDATION_COLUMNS = [
    "gripping_rate",
    "diff_vs_best_rule",
    "diff_ci",
    "best_rule",
    "best_rule_gripping_rate",
    "beats_best_rule",
]
"""The figures of one validation (:func:`validate`), the last columns of every eval.csv."""


def validation_seeds(n: int) -> list[int]:
    """The first ``n`` validation seeds."""
    return [VALIDATION_SEED_BASE + i for i in range(n)]


def eval_scenario(scenario: Scenario, mode: str, duration: float) -> Scenario:
    """The scenario of evaluation runs: the mode's termination, a shorter feeding time."""
    warmup = min(scenario.warmup, duration / 5.0)
    return with_overrides(
        scenario, {"termination": TERMINATION[mode], "duration": duration, "warmup": warmup}
    )


def rule_baselines(
    scenario: Scenario, seeds: list[int], engine: str = "simpy", ran: set[str] | None = None
) -> dict[str, list[float]]:
    """Gripping rate per seed of every single rule (common random numbers).

    ``engine``: :func:`twin.run.simulate`'s (same results on each); the engines that ran
    are added to ``ran`` when given."""
    from pnp_twin.policies.registry import make_policy

    out: dict[str, list[float]] = {}
    for r in RULES:
        results = [simulate(scenario, make_policy(r), seed=s, engine=engine) for s in seeds]
        out[r] = [res.kpis["gripping_rate"] for res in results]
        if ran is not None:
            ran.update(str(res.meta.get("engine", "simpy")) for res in results)
    return out


def validate(
    policy: Policy,
    scenario: Scenario,
    seeds: list[int],
    baselines: dict[str, list[float]],
    engine: str = "simpy",
) -> dict[str, Any]:
    """The greedy ``policy`` on the validation ``seeds`` against the best single rule there
    (``baselines`` from :func:`rule_baselines`; paired, the same seeds for both): the
    :data:`VALIDATION_COLUMNS`. It beats the rule when the paired 95 % interval is above 0.
    ``engine``: :func:`twin.run.simulate`'s (same results on each)."""
    best = max(baselines, key=lambda r: float(np.mean(baselines[r])))
    runs = [simulate(scenario, policy, seed=s, engine=engine) for s in seeds]
    g = [r.kpis["gripping_rate"] for r in runs]
    diff = np.asarray(g) - np.asarray(baselines[best])
    d_mean, d_low, _ = t_interval(list(diff), 0.95)
    return {
        "gripping_rate": float(np.mean(g)),
        "diff_vs_best_rule": d_mean,
        "diff_ci": d_mean - d_low,
        "best_rule": best,
        "best_rule_gripping_rate": float(np.mean(baselines[best])),
        "beats_best_rule": int(d_low > 0.0),
    }
