"""Rule-mix search: the best per-robot mix of dispatching rules for one line.

A mix gives each robot its own rule, e.g. ``SPT,SPT,SPT,FIFO`` (Huang et al. 2015 found
"SPT upstream, FIFO on the last robot" best). Every mix is evaluated on the same
replications (common random numbers) by its mean gripping rate. Where RULES^N is at most
``EXHAUSTIVE_LIMIT`` mixes every mix is run; beyond, a GRASP (greedy randomised adaptive
search, as Huang et al.) runs within a budget of mixes:

1. evaluate every uniform mix (one rule on all robots) and start from the best;
2. construction: robot by robot, upstream first, try every rule at that position (the
   others as they stand), keep the rules within ``alpha`` of the best of them
   (the restricted candidate list) and draw one at random from the search generator;
3. local search: best improvement over the mixes that change one robot's rule, until none
   improves;
4. repeat 2-3 while the budget lasts, or until ``MAX_STALE`` iterations in a row evaluate no
   new mix (every mix they reach is known: the search has converged, which a small mix space
   reaches before any budget); the ranking covers every mix evaluated.

The search is deterministic for a master seed (its generator is a child stream of it), so a
resumed search replays the same path and reuses the journaled runs.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.policies import RULES
from pnp_twin.policies.registry import rule_names
from pnp_twin.studies.costing import study_costs
from pnp_twin.studies.folder import Tables
from pnp_twin.studies.plan import StudyError, StudyPlan, build_plan
from pnp_twin.studies.runner import Options, Session, finish, open_session
from pnp_twin.studies.seeds import search_rng
from pnp_twin.twin.output import write_json
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

log = logging.getLogger(__name__)

EXHAUSTIVE_LIMIT = 250
DEFAULT_BUDGET = 150
ALPHA = 0.3
MAX_STALE = 20  # GRASP stops when this many constructions in a row find no new mix


def mix_name(rules: Sequence[str]) -> str:
    """``["SPT", "FIFO"]`` -> ``"SPT,FIFO"``."""
    return ",".join(rules)


class MixSearch:
    """Evaluates mixes in batches (one backend call per batch), caching mean G per mix."""

    def __init__(
        self, scenario: Scenario, session: Session, replications: int, budget: int
    ) -> None:
        self.scenario = scenario
        self.session = session
        self.replications = replications
        self.budget = budget
        self.order: list[str] = []
        self.scores: dict[str, float] = {}
        self.rows: dict[str, list[dict[str, Any]]] = {}
        self.stopped = "exhausted"  # why the search ended: exhausted, budget or converged

    @property
    def left(self) -> int:
        return self.budget - len(self.order)

    def evaluate(self, mixes: Sequence[str]) -> dict[str, float]:
        """Mean gripping rate of each mix (new ones run, within the budget)."""
        new = [m for m in dict.fromkeys(mixes) if m not in self.scores][: max(self.left, 0)]
        if new:
            plan = self.plan(new)
            specs = plan.specs()
            self.session.plan_more(len(specs))
            for spec, row in zip(specs, self.session.run(specs), strict=True):
                self.rows.setdefault(spec.policy, []).append(row)
            for m in new:
                self.order.append(m)
                self.scores[m] = float(np.mean([r["gripping_rate"] for r in self.rows[m]]))
        return {m: self.scores[m] for m in mixes if m in self.scores}

    def plan(self, mixes: Sequence[str]) -> StudyPlan:
        """The one-point study plan of ``mixes``."""
        return build_plan(self.scenario, grid={}, policies=mixes, replications=self.replications)


def exhaustive(search: MixSearch, rules: Sequence[str], n: int) -> None:
    """Evaluate every mix of ``rules`` over ``n`` robots."""
    search.evaluate([mix_name(c) for c in itertools.product(rules, repeat=n)])


def grasp(
    search: MixSearch, rules: Sequence[str], n: int, rng: np.random.Generator, alpha: float
) -> None:
    """Greedy randomised construction + best-improvement local search, within the budget."""
    uniform = search.evaluate([mix_name([r] * n) for r in rules])
    start = max(uniform, key=uniform.__getitem__).split(",")
    stale = 0  # constructions in a row that found no mix not yet evaluated
    while search.left > 0 and stale < MAX_STALE:
        known = len(search.order)
        _construct_and_improve(search, rules, n, rng, alpha, list(start))
        stale = stale + 1 if len(search.order) == known else 0
    search.stopped = "budget" if search.left <= 0 else "converged"


def _construct_and_improve(
    search: MixSearch,
    rules: Sequence[str],
    n: int,
    rng: np.random.Generator,
    alpha: float,
    current: list[str],
) -> None:
    """One GRASP iteration: randomised greedy construction, then local search."""
    for i in range(n):  # construction, upstream first
        options = {r: mix_name(current[:i] + [r] + current[i + 1 :]) for r in rules}
        scores = search.evaluate(list(options.values()))
        scored = {r: scores[m] for r, m in options.items() if m in scores}
        if not scored:
            return
        top, low = max(scored.values()), min(scored.values())
        rcl = [r for r, s in scored.items() if s >= top - alpha * (top - low)]
        current[i] = rcl[int(rng.integers(len(rcl)))]
    score = search.scores[mix_name(current)]
    while search.left > 0:  # local search: best single-robot change
        near = [
            mix_name(current[:i] + [r] + current[i + 1 :])
            for i in range(n)
            for r in rules
            if r != current[i]
        ]
        scores = search.evaluate(near)
        if not scores:
            return
        best = max(scores, key=scores.__getitem__)
        if scores[best] <= score:
            break
        current, score = best.split(","), scores[best]


def rank(search: MixSearch, confidence: float) -> list[dict[str, Any]]:
    """Every evaluated mix with its mean and CI, best first (ties: evaluation order)."""
    out = []
    for m in search.order:
        mean, low, high = t_interval([r["gripping_rate"] for r in search.rows[m]], confidence)
        low, high = max(low, 0.0), min(high, 100.0)  # G is a percentage, as in sweep's tables
        out.append({"mix": m, "gripping_rate_mean": mean, "ci_low": low, "ci_high": high})
    return sorted(out, key=lambda r: -r["gripping_rate_mean"])


def margin(
    search: MixSearch, ranked: Sequence[dict[str, Any]], confidence: float
) -> dict[str, Any] | None:
    """The best mix minus the runner-up, paired by replication (common random numbers)."""
    if len(ranked) < 2:
        return None
    first, second = ranked[0]["mix"], ranked[1]["mix"]
    by_rep = {r["replication"]: r["gripping_rate"] for r in search.rows[second]}
    diff = [r["gripping_rate"] - by_rep[r["replication"]] for r in search.rows[first]]
    mean, low, high = t_interval(diff, confidence)
    return {
        "best": first,
        "runner_up": second,
        "diff_mean": mean,
        "ci_low": low,
        "ci_high": high,
        "n": len(diff),
        # apart only when the paired interval exists and excludes zero
        "distinguishable": bool(np.isfinite(low) and low > 0),
    }


def check_mix(
    scenario: Scenario,
    rules: Sequence[str] | None = None,
    replications: int | None = None,
    budget: int = DEFAULT_BUDGET,
) -> list[str]:
    """The rules a mix search of ``scenario`` mixes, every setting checked (rules, budget,
    the line with each rule on every robot), before its folder is touched."""
    sweep = scenario.sweep
    if rules is None or len(rules) == 0:
        rules = list(sweep.policies) if sweep and sweep.policies else list(RULES)
    try:
        rules = list(rule_names(rules))
    except ValueError as e:
        raise StudyError(f"mix: {e}") from None
    if len(set(rules)) != len(rules):
        raise StudyError(f"mix: the rules {rules} name a rule twice")
    if budget < 1:
        raise StudyError(f"--budget: {budget} is not allowed; give 1 or more mixes")
    n = scenario.robots.count
    every = [mix_name([r] * n) for r in rules]
    build_plan(scenario, grid={}, policies=every, replications=replications)
    return rules


def run_mix(
    scenario: Scenario,
    out: Path,
    options: Options,
    rules: Sequence[str] | None = None,
    replications: int | None = None,
    budget: int = DEFAULT_BUDGET,
    alpha: float = ALPHA,
) -> tuple[Tables, dict[str, Any]]:
    """Search the best rule mix of ``scenario``'s line into ``out``; tables and mix.json."""
    rules = check_mix(scenario, rules, replications, budget)
    n = scenario.robots.count
    method = "exhaustive" if len(rules) ** n <= EXHAUSTIVE_LIMIT else "grasp"
    base = build_plan(scenario, grid={}, policies=[rules[0]], replications=replications)
    line = base.scenario.model_copy(update={"sweep": None})
    extra = {"rules": rules, "method": method, "budget": budget, "alpha": alpha}
    definition_plan = build_plan(line, grid={}, policies=[], replications=base.replications)
    session = open_session(out, definition_plan, "mix", options, extra)
    search = MixSearch(
        line, session, base.replications, len(rules) ** n if method == "exhaustive" else budget
    )
    if method == "exhaustive":
        exhaustive(search, rules, n)
    else:
        grasp(search, rules, n, search_rng(scenario.seed), alpha)
    plan = search.plan(search.order)
    rows = [row for m in search.order for row in search.rows[m]]
    ranked = rank(search, options.confidence)
    mix = {
        "method": method,
        "rules": rules,
        "ranked": ranked,
        "best": ranked[0]["mix"],
        "margin": margin(search, ranked, options.confidence),
        "evaluated": len(search.order),
        "budget": search.budget,
        "stopped": search.stopped,
        "replications": base.replications,
    }
    tables = finish(session, plan, "mix", rows, {"method": method, "rules": rules})
    if options.costs is not None:  # --costs: each mix's total cost, as meta.json has it
        priced = study_costs(plan, tables, options.costs, options.costs_file)["rows"]
        cost = {r["policy"]: r["total_cost"] for r in priced}
        for r in ranked:
            r["total_cost"] = cost.get(r["mix"])
    write_json(mix, out / "mix.json", keep_nan=True)
    log.info("mix search (%s): best %s of %d mixes", method, mix["best"], len(search.order))
    return tables, mix
