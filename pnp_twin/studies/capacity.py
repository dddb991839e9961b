"""Capacity: the highest part flow a line sustains at a target gripping rate.

G falls as the part flow rises. With common random numbers (replication k sees the same
seed at every flow) the mean G, and its lower and upper confidence bounds, are smooth
decreasing functions of the flow, so each crossing of the target is found by root finding
(a bracket grown by doubling or halving from the scenario's own flow, then bisection to a
relative tolerance), not a grid:

* ``max_rate``: the highest flow whose mean G reaches the target;
* ``ci_low``: the highest flow whose lower confidence bound does (what can be promised);
* ``ci_high``: the highest flow whose upper bound does (beyond it the line surely misses).

With several rules, the answer is the capacity of the best rule, picked after seeing the
data: each rule's interval is taken at the Bonferroni level (``sizing.selected_confidence``),
so all of them hold together with the stated confidence, and each crossing is judged by the
largest value over the rules at each flow (the best rule's G is at least the largest lower
bound and at most the largest upper bound). So ``max_rate`` is the highest mean crossing of
any rule, ``ci_low`` the highest lower crossing (the promise, valid for the rule that
reaches it: ``policy``) and ``ci_high`` the highest upper crossing of any rule (beyond it no
rule meets the target); ``policies`` names the rule of each crossing. With G falling in the
flow for every rule these are the largest of each rule's own crossings.

Every run is journalled in ``DIR/evals/`` the moment it finishes (as calibrate does: the
runs store of :mod:`pnp_twin.studies.runstore`, and each finished flow keyed by the
scenario, rules and seeds), so a killed search resumes without running a finished run again,
and asking again with another target or confidence replays the flows it needs and
simulates only new ones. ``DIR/capacity.json`` holds the
answer and the curve of G against flow (every evaluated flow).

With ``vary`` (``PATH=LO:HI`` whole numbers or ``PATH=V1,V2,...``, as in ``design``) the
search runs for every combination of the varied fields: ``configurations`` holds each one's
choice, crossings and curve, and the top-level answer is the first configuration's. Each
configuration's interval is its own (no selection is made among them).
"""

from __future__ import annotations

import contextlib
import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies.backends import Executor
from pnp_twin.studies.calibrate_eval import EVALS, Evaluator
from pnp_twin.studies.design_text import choice_text
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.runstore import RunStore
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.studies.sizing import selected_confidence
from pnp_twin.studies.vary import parse_vary
from pnp_twin.twin.loader import ScenarioError, with_overrides
from pnp_twin.twin.output import write_json
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

SUMMARY_FILE = "capacity.json"
TOLERANCE = 0.01  # relative width of the final bracket
MAX_STEPS = 8  # doublings or halvings while bracketing
MAX_BISECTIONS = 12
RATE_DIGITS = 4  # flows are rounded to 4 significant digits (reused across questions)
CRITERIA = {"max_rate": "mean", "ci_low": "low", "ci_high": "high"}
MIN_FLOW, MAX_FLOW = 0.001, 1000.0  # parts/s: the scenario schema's bounds on feeder.rate
MAX_REPLICATIONS = 1000  # per flow
AUTO_FIRST = 5  # --replications auto starts here and doubles
AUTO_MOST = 80  # ... up to this many (--max-replications)
GAP = 0.05  # ... until the promise is within this share of the mean crossing (--gap)


def _round(rate: float) -> float:
    return float(f"{rate:.{RATE_DIGITS}g}")


class Capacity:
    """The flows evaluated so far, and the search for each crossing."""

    def __init__(
        self,
        scenario: Scenario,
        evaluator: Evaluator,
        target: float,
        confidence: float,
        progress: Callable[[int], None] | None = None,
        name: str = "",
        column: str = "gripping_rate",
    ) -> None:
        self.name = name  # the configuration, in the journal's labels ("" for the first)
        self.scenario = scenario
        self.evaluator = evaluator
        self.target = target
        self.column = column  # the runs' figure the target is on (--kpi)
        self.confidence = confidence
        self.level = selected_confidence(confidence, len(evaluator.policies))
        self.points: dict[float, dict[str, Any]] = {}
        self.progress = progress

    def at(self, rate: float) -> dict[str, Any]:
        """G at flow ``rate``: each rule's mean and bounds (at the selection-safe level) in
        ``rules``, and the best rule's: ``mean``, ``low``, ``high`` are the largest over
        the rules (each bound a valid one for the best rule's G, since every rule's
        interval holds together), ``policy`` the rule with the highest lower bound."""
        rate = _round(rate)
        if rate in self.points:
            return self.points[rate]
        try:
            sc = with_overrides(self.scenario, {"feeder.rate": rate})
        except ScenarioError as e:
            raise StudyError(f"capacity: flow {rate:g} parts/s: {e}") from None
        runs = self.evaluator.runs([sc], [f"{self.name}flow {rate:g}"])[0]
        each = {rule: self._bounds(rows) for rule, rows in runs.items()}
        point: dict[str, Any] = {"rate": rate, "rules": each}
        for key in ("mean", "low", "high"):
            finite = [b[key] for b in each.values() if math.isfinite(b[key])]
            point[key] = max(finite, default=math.nan)
        # no part in the window at this flow (G undefined): nothing is lost, the flow is low
        point["empty"] = all(not math.isfinite(b["mean"]) for b in each.values())
        point["policy"] = max(each, key=lambda r: (each[r]["low"], each[r]["mean"]))
        self.points[rate] = point
        if self.progress is not None:
            self.progress(len(self.points))
        return point

    def _bounds(self, rows: Sequence[Mapping[str, Any]]) -> dict[str, float]:
        mean, low, high = t_interval([r[self.column] for r in rows], self.level)
        low = max(low, 0.0) if math.isfinite(low) else mean
        high = min(high, 100.0) if math.isfinite(high) else mean
        return {"mean": mean, "low": low, "high": high}

    def rule_at(self, rate: float | None, key: str) -> str | None:
        """The rule whose ``key`` (mean, low or high) is the largest at ``rate``: the rule
        a crossing of that key belongs to."""
        if rate is None:
            return None
        each = self.at(rate)["rules"]
        return str(max(each, key=lambda r: (each[r][key], each[r]["mean"])))

    def ok(self, rate: float, key: str) -> bool:
        """Whether ``key`` reaches the target at ``rate`` (a flow that brings no part in
        the window loses none: it counts as reached, so the search moves up from it)."""
        point = self.at(rate)
        return bool(point["empty"] or point[key] >= self.target)

    def _step(self, rate: float) -> int:
        """A doubling or halving step counts unless it landed on an empty flow."""
        return 0 if self.at(rate)["empty"] else 1

    def crossing(self, key: str, start: float) -> tuple[float | None, str]:
        """The highest flow whose ``key`` (mean, low or high) reaches the target, and how
        the search ended ("found", "above": still met at the highest flow tried, "below":
        not met at the lowest)."""
        passing = [r for r in self.points if self.ok(r, key)]
        failing = [r for r in self.points if not self.ok(r, key)]
        lo = max(passing, default=None)
        hi = min((r for r in failing if lo is None or r > lo), default=None)
        if lo is None and hi is None:
            if self.ok(start, key):
                lo = start
            else:
                hi = start
        steps = 0
        while hi is None:  # grow until the target is missed
            assert lo is not None
            if steps >= MAX_STEPS or lo >= MAX_FLOW:
                return lo, "above"
            r = min(_round(lo * 2), MAX_FLOW)
            steps += self._step(r)
            if self.ok(r, key):
                lo = r
            else:
                hi = r
        while lo is None:  # shrink until the target is met
            if steps >= MAX_STEPS or hi <= MIN_FLOW:
                return None, "below"
            r = max(_round(hi / 2), MIN_FLOW)
            steps += self._step(r)
            if self.ok(r, key):
                lo = r
            else:
                hi = r
        for _ in range(MAX_BISECTIONS):
            if (hi - lo) <= TOLERANCE * lo:
                break
            mid = _round((lo + hi) / 2)
            if mid in (lo, hi):
                break
            if self.ok(mid, key):
                lo = mid
            else:
                hi = mid
        return lo, "found"


def check_capacity(
    scenario: Scenario,
    target: float,
    confidence: float = 0.95,
    replications: int = 5,
    vary: Sequence[str] = (),
    start: float | None = None,
    gap: float = GAP,
    most: int = AUTO_MOST,
) -> list[dict[str, Any]]:
    """Every check of a capacity question before anything is written; returns the
    combinations of the varied fields ([{}] without any), or raises a one-line StudyError."""
    if not 0 < target <= 100:
        raise StudyError(f"--target: {target:g} is not allowed; give a percentage in (0, 100]")
    if not 0 < confidence < 1:
        raise StudyError(f"--confidence: {confidence:g} is not allowed; give 0 < c < 1")
    if not 2 <= replications <= MAX_REPLICATIONS:
        raise StudyError(
            f"--replications: {replications} is not allowed; give 2 to {MAX_REPLICATIONS}"
        )
    if not (math.isfinite(gap) and 0 < gap < 1):
        raise StudyError(f"--gap: {gap:g} is not allowed; give a share between 0 and 1, e.g. 0.05")
    if not 2 <= most <= MAX_REPLICATIONS:
        raise StudyError(f"--max-replications: {most} is not allowed; give 2 to {MAX_REPLICATIONS}")
    if start is not None and not (math.isfinite(start) and MIN_FLOW <= start <= MAX_FLOW):
        raise StudyError(
            f"--start: {start:g} parts/s is not allowed; give a flow from {MIN_FLOW:g} to "
            f"{MAX_FLOW:g} parts/s"
        )
    grid: dict[str, list[Any]] = {}
    for spec in vary:
        path, values = parse_vary(spec)
        if path in grid:
            raise StudyError(f"--vary {path}: given twice; give each field once")
        if not isinstance(values, list):
            raise StudyError(
                f"--vary {spec}: capacity takes a list or a range of whole numbers (a "
                "continuous range is for design)"
            )
        if path == "feeder.rate":
            raise StudyError("--vary feeder.rate: the part flow is what capacity searches")
        grid[path] = values
    combos = [dict(zip(grid, c, strict=True)) for c in itertools.product(*grid.values())]
    for point in combos:
        try:
            sc = with_overrides(scenario, point) if point else scenario
        except ScenarioError as e:
            raise StudyError(f"--vary {point}: {e}") from None
        if sc.feeder.arrival == "trace":
            raise StudyError(
                "capacity: a replayed trace fixes the part flow; add --set "
                "feeder.arrival=poisson (or normal) to search the flow at the trace's variability"
            )
    return combos


def parse_replications(text: str) -> int | str:
    """``-r``: a whole number of replications per flow, or "auto"."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise StudyError(
            f"--replications: '{text[:40]}' is not allowed; give a whole number (2 to "
            f"{MAX_REPLICATIONS}) or auto"
        ) from None


def _crossings(cap: Capacity, first: float) -> dict[str, tuple[float | None, str]]:
    """The three crossings, searched again until none moves: each is searched among every
    flow evaluated so far, so a later search's flows can move an earlier crossing (where G
    is not quite monotone in the flow) and the answer always reads promise <= mean <= upper."""
    cross = {name: cap.crossing(key, first) for name, key in CRITERIA.items()}
    for _ in range(3):
        again = {name: cap.crossing(key, first) for name, key in CRITERIA.items()}
        if again == cross:
            break
        cross = again
    return cross


def _search(
    sc: Scenario,
    ev: Evaluator,
    values: dict[str, Any],
    name: str,
    first: float,
    question: tuple[float, float, KpiChoice],
    progress: Callable[[int], None] | None,
) -> dict[str, Any]:
    """One configuration's capacity with the evaluator's replications."""
    target, confidence, kpi = question
    cap = Capacity(sc, ev, target, confidence, progress, name, kpi.column)
    cross = _crossings(cap, first)
    by = {name: cap.rule_at(cross[name][0], key) for name, key in CRITERIA.items()}
    one: dict[str, Any] = {
        "choice": values,
        "max_rate": cross["max_rate"][0],
        "ci_low": cross["ci_low"][0],
        "ci_high": cross["ci_high"][0],
        "search": {k: v[1] for k, v in cross.items()},
        "policy": by["ci_low"] or by["max_rate"],  # the rule the promise is for
        "policies": by,
        "robots": sc.robots.count,
        "curve": sorted(cap.points.values(), key=lambda p: p["rate"]),
        "confidence": confidence,
        "target": target,
        "replications": len(ev.seeds),
    }
    one["flows_evaluated"] = one["evaluated"] = len(one["curve"])
    return one


def promise_gap(one: Mapping[str, Any]) -> float:
    """How far the promise sits below the mean crossing, as a share of the mean crossing
    (inf when either is missing): what ``--replications auto`` shrinks."""
    mean, low = one.get("max_rate"), one.get("ci_low")
    if not mean or low is None:
        return math.inf
    return max(0.0, (mean - low) / mean)


def run_capacity(
    scenario: Scenario,
    out: Path,
    target: float,
    confidence: float = 0.95,
    policies: Sequence[str] | None = None,
    replications: int | str = 5,
    workers: int = 1,
    engine: str = "auto",
    start: float | None = None,
    command: str = "",
    progress: Callable[[int], None] | None = None,
    vary: Sequence[str] = (),
    kpi: KpiChoice = GRIPPING,
    executor: Executor | None = None,
    gap: float = GAP,
    most: int = AUTO_MOST,
) -> dict[str, Any]:
    """Find the line's capacity at ``target`` into ``out``; returns capacity.json's mapping.
    With a ``kpi`` other than G the target and the curve's mean and bounds are on that
    figure, which ``kpi`` names. ``replications="auto"``: from :data:`AUTO_FIRST`, doubled
    (up to ``most``) while the promise sits more than ``gap`` (a share) below the mean
    crossing. Every batch runs on ``executor`` (one pool for the whole search; a local one
    of ``workers`` processes when None)."""
    auto = replications == "auto"
    first_n = AUTO_FIRST if auto else int(replications)
    combos = check_capacity(scenario, target, confidence, first_n, vary, None, gap, most)
    rules = list(policies or [scenario.policy])
    t0 = time.perf_counter()
    kept = ["part_flow", "throughput"] + ([] if kpi.column == "gripping_rate" else [kpi.column])
    first = _round(start if start is not None else scenario.feeder.rate)
    found: list[dict[str, Any]] = []
    counts = {"runs_simulated": 0, "runs_replayed": 0}
    store = RunStore(Path(out) / EVALS)  # one store for every round: opened once
    with contextlib.ExitStack() as stack:
        if executor is None:
            executor = stack.enter_context(Executor("local", workers))
        for i, values in enumerate(combos):
            sc = with_overrides(scenario, values) if values else scenario
            name = "".join(f"{k}={v}, " for k, v in values.items()) if i else ""
            n, tried = first_n, []
            while True:
                seeds = replication_seeds(scenario.seed, n)
                ev = Evaluator(out, rules, seeds, kept, workers, engine, store, executor)
                one = _search(sc, ev, values, name, first, (target, confidence, kpi), progress)
                counts["runs_simulated"] += ev.runs_simulated
                counts["runs_replayed"] += ev.runs_replayed + ev.runs_from_points
                tried.append(n)
                if not auto or promise_gap(one) <= gap or n >= most:
                    break
                n = min(most, 2 * n)
            if auto:
                one["auto"] = {"gap": gap, "reached": promise_gap(one), "replications": tried}
            one["text"] = capacity_text(one, kpi)
            found.append(one)
    head = found[0]
    result: dict[str, Any] = {
        "target": target,
        "confidence": confidence,
        **({} if kpi.default else {"kpi": kpi.to_json()}),
        "max_rate": head["max_rate"],
        "ci_low": head["ci_low"],
        "ci_high": head["ci_high"],
        "search": head["search"],
        "policy": head["policy"],
        "policies": head["policies"],
        "rules": rules,
        "confidence_each": selected_confidence(confidence, len(rules)),
        "replications": head["replications"],
        **({"auto": head["auto"]} if auto else {}),
        "seeds": replication_seeds(scenario.seed, head["replications"]),
        "tolerance": TOLERANCE,
        "curve": head["curve"],
        "flows_evaluated": sum(c["evaluated"] for c in found),
        "evaluated": sum(c["evaluated"] for c in found),
        **counts,
        "scenario": scenario.model_dump(mode="json"),
        "scenario_name": scenario.name,
        "robots": head["robots"],
        "duration": scenario.duration,
        "warmup": scenario.warmup,
        "engine": engine,
        "backend": executor.backend if executor is not None else "local",
        "command": command,
        "wall_time": time.perf_counter() - t0,
    }
    if vary:
        result["vary"] = {k: sorted({c["choice"][k] for c in found}) for k in combos[0]}
        result["configurations"] = [{k: v for k, v in c.items() if k != "target"} for c in found]
    result["text"] = head["text"] if not vary else " ".join(c["text"] for c in found)
    write_json(result, Path(out) / SUMMARY_FILE, keep_nan=True)
    return result


def _line(c: Mapping[str, Any]) -> str:
    """'6 robots', or '6 robots, arm speed 4 m/s' for a configuration with a choice."""
    choice = {k: v for k, v in (c.get("choice") or {}).items()}
    choice.setdefault("robots.count", c["robots"])
    choice = {"robots.count": choice.pop("robots.count"), **choice}
    return choice_text({**choice, "policy": ""}).removesuffix(" running ")


def capacity_text(c: dict[str, Any], kpi: KpiChoice = GRIPPING) -> str:
    """The answer worded as a promise: 'With 6 robots running SPT you can promise 16.4
    parts/s at G ≥ 95 % with 95 % confidence; the mean crosses at 19.6 parts/s, and above
    21.0 parts/s the line misses it with 95 % confidence.' Each crossing the search could
    not pin down (still met at the highest flow tried, or not met at the lowest) is said so."""
    n, conf = _line(c), f"{100 * c['confidence']:g} %"
    goal = f"{kpi.short} ≥ {c['target']:g} %"
    curve = c.get("curve") or []
    highest = max((p["rate"] for p in curve), default=None)
    lowest = min((p["rate"] for p in curve), default=None)
    at_high = f" ({highest:.3g} parts/s)" if highest is not None else ""
    at_low = f" ({lowest:.3g} parts/s)" if lowest is not None else ""
    if c["max_rate"] is None:
        return f"With {n} no flow tried reaches {goal}, even the lowest{at_low}."
    lo, hi, mean = c["ci_low"], c["ci_high"], c["max_rate"]
    by = c.get("policies") or {}
    mean_rule = by.get("max_rate") or c.get("policy")
    several = len({r for r in by.values() if r}) > 1
    after = " after picking the rule" if several else ""
    if lo is None:
        out = (
            f"With {n} no flow tried can be promised at {goal} with {conf} confidence (the "
            f"lower bound misses it even at the lowest flow tried{at_low})"
        )
    else:
        rule = f" running {c['policy']}" if c.get("policy") else ""
        out = f"With {n}{rule} you can promise {lo:.3g} parts/s at {goal}"
        out += f" with {conf} confidence{after}"
    whose = f" ({mean_rule}'s)" if several and mean_rule != c.get("policy") else ""
    if c["search"]["max_rate"] == "above":
        out += f"; the mean{whose} still meets it at the highest flow tried{at_high}"
    else:
        out += f"; the mean{whose} crosses at {mean:.3g} parts/s"
    if hi is None or c["search"].get("ci_high") == "above":
        out += (
            f"; the upper bound still reaches it at the highest flow tried{at_high}, so no flow "
            f"was found where the line misses it with {conf} confidence"
        )
    else:
        out += f", and above {hi:.3g} parts/s the line misses it with {conf} confidence"
    gap = promise_gap(c)
    if "auto" not in c and c.get("replications") and GAP < gap < math.inf:
        out += (
            f" ({c['replications']} replications per flow leave the promise "
            f"{100 * gap:.0f} % below the mean crossing; -r auto adds replications until it "
            f"is within {100 * GAP:g} %)"
        )
    return out + "."
