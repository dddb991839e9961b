"""Evaluating a trained HDQN against every rule and the best rule mix, paired by seed.

Every policy runs on the same held-out seeds (common random numbers: the same part stream
for every policy), so each comparison is a paired one: the confidence interval is the
t-interval of the per-seed differences ``G_hdqn - G_policy``. Evaluation seeds default to
0..n-1, disjoint from training (>= 1,000,000) and validation (500,000 + i) seeds.

The best static rule mix is either given (a mix such as ``SPT,SPT,SPT,FIFO``, e.g. the
``best`` of a ``pnp-twin mix`` study) or searched here by coordinate ascent from the best
single rule on separate tuning seeds (600,000 + i), so that choosing the mix does not use
the evaluation seeds.

:func:`write_evaluation` saves a comparison into a run folder for the training report:
``evaluation.csv`` (one row per policy and seed) and ``rules.csv`` (how often the HDQN
chose each rule per robot on the first evaluation seed, the paper's figure 13).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from pnp_twin.policies.registry import make_policy
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Policy
from pnp_twin.twin.loader import with_overrides
from pnp_twin.twin.output import write_table
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval
from pnp_twin.twin.trace import for_replication

log = logging.getLogger(__name__)

TUNING_SEED_BASE = 600_000


@dataclass(frozen=True)
class Comparison:
    """The result of :func:`compare`: a table (one row per policy) and the per-seed runs."""

    table: pd.DataFrame
    runs: pd.DataFrame
    mix: str
    seeds: list[int]
    reference: str
    scenario: Scenario | None = None
    engines: dict[str, str] = field(default_factory=dict)  # policy -> the engine that ran it


def gripping_rates(
    scenario: Scenario, make: Callable[[], Policy], seeds: Sequence[int], engine: str = "simpy"
) -> list[float]:
    """Gripping rate of a fresh policy per seed (``engine``: see :func:`twin.run.simulate`)."""
    return _rates(scenario, make, seeds, engine)[0]


def _rates(
    scenario: Scenario, make: Callable[[], Policy], seeds: Sequence[int], engine: str
) -> tuple[list[float], str]:
    """Gripping rate per seed and the engine that ran (the last run's; a policy runs on one)."""
    results = [  # seed k replays trace k of a folder of traces
        simulate(for_replication(scenario, k), make(), seed=s, engine=engine)
        for k, s in enumerate(seeds)
    ]
    ran = results[-1].meta.get("engine", "simpy") if results else engine
    return [r.kpis["gripping_rate"] for r in results], str(ran)


def search_mix(
    scenario: Scenario,
    seeds: Sequence[int],
    rules: Sequence[str] = tuple(RULES),
    sweeps: int = 2,
    engine: str = "simpy",
) -> str:
    """The best per-robot mix found by coordinate ascent from the best uniform rule."""
    n = scenario.robots.count
    cache: dict[tuple[str, ...], float] = {}

    def score(mix: tuple[str, ...]) -> float:
        if mix not in cache:
            cache[mix] = float(
                np.mean(gripping_rates(scenario, lambda: make_policy(",".join(mix)), seeds, engine))
            )
        return cache[mix]

    best = max(((r,) * n for r in rules), key=score)
    for _ in range(sweeps):
        improved = False
        for i in range(n):
            for r in rules:
                mix = best[:i] + (r,) + best[i + 1 :]
                if score(mix) > score(best):
                    best, improved = mix, True
        if not improved:
            break
    log.info("mix search: %s (%.2f %%) after %d mixes", ",".join(best), score(best), len(cache))
    return ",".join(best)


def compare(
    scenario: Scenario,
    hdqn: str | Path,
    seeds: int = 20,
    first_seed: int = 0,
    mix: str | None = None,
    duration: float | None = None,
    termination: str | None = None,
    tuning_seeds: int = 3,
    confidence: float = 0.95,
    engine: str = "simpy",
) -> Comparison:
    """Compare the HDQN in folder ``hdqn`` (or an ``sb3:MODEL.zip`` spec) with every rule
    and the best mix on ``seeds`` seeds.

    ``duration`` and ``termination`` override the scenario's for every policy alike.
    ``engine`` (simpy | fast | auto, same results) runs every policy (the trained one, a
    Python object, through the fast engine's callback). ``Comparison.engines`` says which
    engine ran each policy.
    """
    changes: dict[str, object] = {}
    if duration is not None:
        changes.update(duration=duration, warmup=min(scenario.warmup, duration / 5.0))
    if termination is not None:
        changes["termination"] = termination
    line = with_overrides(scenario, changes) if changes else scenario
    seed_list = list(range(first_seed, first_seed + seeds))
    if mix is None:
        tuning = [TUNING_SEED_BASE + i for i in range(tuning_seeds)]
        mix = search_mix(line, tuning, engine=engine)
    reference, make_trained = trained_policy(hdqn)
    makers: dict[str, Callable[[], Policy]] = {reference: make_trained}
    for r in [*RULES, mix]:
        makers[r if r in RULES else f"mix {r}"] = partial(make_policy, r)
    engines: dict[str, str] = {}
    g: dict[str, list[float]] = {}
    for name, make in makers.items():
        g[name], engines[name] = _rates(line, make, seed_list, engine)
    ref = np.asarray(g[reference])
    rows = []
    for name, values in g.items():
        mean, low, high = t_interval(values, confidence)
        d_mean, d_low, d_high = t_interval(list(ref - np.asarray(values)), confidence)
        rows.append(
            {
                "policy": name,
                "gripping_rate": mean,
                "ci_low": low,
                "ci_high": high,
                "diff": d_mean if name != reference else float("nan"),
                "diff_ci_low": d_low if name != reference else float("nan"),
                "diff_ci_high": d_high if name != reference else float("nan"),
            }
        )
    table = pd.DataFrame(rows)
    runs = pd.DataFrame(
        [
            (name, s, v)
            for name, values in g.items()
            for s, v in zip(seed_list, values, strict=True)
        ],
        columns=["policy", "seed", "gripping_rate"],
    )
    runs["engine"] = runs["policy"].map(engines)
    return Comparison(table, runs, mix, seed_list, reference, line, engines)


def by_name(spec: str) -> bool:
    """Whether ``spec`` names a policy the registry makes (``sb3:MODEL.zip``, the lookahead
    controller) rather than an HDQN folder."""
    if spec.startswith("sb3:"):
        return True
    return (spec == "lookahead" or spec.startswith("lookahead:")) and not Path(spec).is_dir()


def trained_policy(trained: str | Path) -> tuple[str, Callable[[], Policy]]:
    """The name and a fresh-policy maker of an HDQN folder or an ``sb3:MODEL.zip`` spec."""
    spec = str(trained)
    if by_name(spec):
        return str(getattr(make_policy(spec), "name", spec)), partial(make_policy, spec)
    from pnp_twin.policies.hdqn.policy import HDQNPolicy

    return f"HDQN ({HDQNPolicy.load(trained).mode})", partial(HDQNPolicy.load, trained)


def verdict(comparison: Comparison) -> dict[str, bool]:
    """Per policy: does the HDQN beat it with the paired CI entirely above zero?"""
    t = comparison.table
    return {
        row.policy: bool(row.diff_ci_low > 0)
        for row in t.itertuples()
        if row.policy != comparison.reference
    }


def policy_kind(name: str, reference: str) -> str:
    """'hdqn', 'rule' or 'mix' for a policy name of a comparison."""
    if name == reference:
        return "hdqn"
    return "rule" if name in RULES else "mix"


def rule_counts(scenario: Scenario, hdqn: str | Path, seed: int) -> pd.DataFrame:
    """How often the HDQN chose each rule per robot in one run: robot, rule, count
    (``NooP`` counts the decisions with no candidate, where no rule was asked)."""
    decisions = simulate(scenario, trained_policy(hdqn)[1](), seed=seed).decisions
    counts = decisions[["robot", "rule", "count"]].copy()
    counts["robot"] = counts["robot"].astype(int)  # the records number robots from 1
    return counts.sort_values(["robot", "rule"]).reset_index(drop=True)


def write_evaluation(comparison: Comparison, hdqn: str | Path, out: str | Path) -> list[Path]:
    """Write ``evaluation.csv`` and ``rules.csv`` of ``comparison`` into folder ``out``.

    ``evaluation.csv``: scenario, mode, termination, duration, policy, kind (hdqn, rule,
    mix), seed, gripping_rate, engine (the one that ran it); one row per policy and seed.
    ``rules.csv``: robot (from 1), rule, count of the HDQN on the first evaluation seed.
    Returns the paths written.
    """
    from pnp_twin.policies.hdqn.checkpoint import read_meta

    spec = str(hdqn)
    mode = spec.partition(":")[0] if by_name(spec) else read_meta(hdqn).get("mode", "")
    line = comparison.scenario
    if line is None:
        raise ValueError("write_evaluation needs a comparison made by compare()")
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    runs = comparison.runs
    table = pd.DataFrame(
        {
            "scenario": line.name,
            "mode": mode,
            "termination": line.termination,
            "duration": line.duration,
            "policy": runs["policy"],
            "kind": [policy_kind(p, comparison.reference) for p in runs["policy"]],
            "seed": runs["seed"],
            "gripping_rate": runs["gripping_rate"],
            "engine": runs["engine"] if "engine" in runs else "simpy",
        }
    )
    paths = [folder / "evaluation.csv", folder / "rules.csv"]
    write_table(table, paths[0])
    write_table(rule_counts(line, hdqn, comparison.seeds[0]), paths[1])
    log.info("evaluation written to %s", folder)
    return paths
