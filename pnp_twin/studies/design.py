"""Design: the cheapest configuration whose gripping rate meets a target with a confidence.

The configurations are every combination of the varied fields (``--vary PATH=LO:HI`` for a
range of whole numbers, ``--vary PATH=V1,V2,...`` for a list) and the rules. A range written
with a decimal point (``--vary robots.arm_speed=2.0:6.0``) is continuous: for each
combination of the discrete fields and the rules, optuna's constrained TPE sampler (seeded
from the scenario's seed) looks for the cheapest point of the continuous box whose lower
confidence bound of G reaches the target, in ``trials`` evaluated points (values rounded to
4 significant digits); every point it evaluates becomes a configuration like the listed ones.
Each configuration's total cost of ownership comes from a cost file (TOML)::

    robot_price = 25000            # per robot; or a table keyed by arm speed in m/s:
    # [robot_price]  "2.0" = 20000   "4.0" = 25000   "6.0" = 32000
    belt_price = 8000              # one number, or a table keyed by belt speed in m/s
    lost_part_cost = 0.05          # per part that reaches the return conveyor
    hours = 4000                   # operating hours the lost parts are counted over

total cost = robots x robot price (at the arm speed; between two priced speeds the price is
interpolated linearly) + belt price (at the belt speed, likewise) +
lost_part_cost x (part flow x (1 - G)) x 3600 x hours, with G the mean gripping rate.

Selection with a confidence that holds after it: every configuration's interval of G is
taken at the Bonferroni level 1 - (1 - c) / (K L) over the K configurations and the L looks
at each (after ``first`` replications and after each doubling up to ``most``: stopping as
soon as a bound crosses the target would otherwise inflate the error), so all intervals
hold together with confidence c and the pick among them keeps it. With a continuous range K
counts every point the optimiser may evaluate (trials per combination), fixed before it
starts, so the pick among the points it did evaluate keeps the confidence too. The procedure is
sequential: every configuration gets ``first`` replications (common random numbers:
replication k has the same seed everywhere); a configuration is *met* when its lower bound
reaches the target, *missed* when its upper bound is below it, *open* otherwise; while an
open configuration could still be cheaper than the cheapest met one, the open ones that
could are doubled in replications (up to ``most``), nowhere else. Every run is journalled
per configuration, rule and seed under ``DIR/evals/`` the moment it finishes
(:mod:`pnp_twin.studies.runstore`), so a killed design resumes without running a finished run
again, and asking again with another target, confidence or cost file simulates only the
replications the new question needs.
"""

from __future__ import annotations

import functools
import itertools
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies.backends import Executor
from pnp_twin.studies.calibrate_eval import EVALS, Evaluator
from pnp_twin.studies.design_answer import answered, question_key
from pnp_twin.studies.design_conditions import conditions_of, is_condition, parse_across
from pnp_twin.studies.design_config import Cell, Config, paired_lost_difference, payback
from pnp_twin.studies.design_text import design_text, line_notes
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.prices import (
    SECONDS_PER_HOUR,
    capital,
    costs_json,
    read_costs,
    robot_prices,
    running_per_part,
)
from pnp_twin.studies.runstore import RunStore
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.studies.vary import Continuous, parse_vary, round_value
from pnp_twin.twin.loader import ScenarioError, load_scenario, with_overrides
from pnp_twin.twin.output import write_json
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import check_replications, for_replication, trace_files

SUMMARY_FILE = "design.json"


def _field(sc: Scenario, path: str) -> Any:
    """The value at a dotted path of a scenario (None where the path is not attributes)."""
    obj: Any = sc
    for part in path.split("."):
        if not hasattr(obj, part):
            return None
        obj = getattr(obj, part)
    return obj


MAX_REPLICATIONS = 1000  # per configuration (a sweep's auto replications stop at 30 by default)
MAX_CONFIGURATIONS = 10_000  # configurations one design may try, counted before expanding


def looks(first: int, most: int) -> int:
    """How many times one configuration's interval may be judged: after ``first``
    replications, then after each doubling up to ``most``."""
    n, count = first, 1
    while n < most:
        n, count = min(most, 2 * n), count + 1
    return count


def parse_grid(vary: Sequence[str]) -> dict[str, Any]:
    """``--vary`` options as {path: values or range}; a path given twice, or a condition of
    the plant (``feeder.*``: what arrives is not bought), is refused."""
    grid: dict[str, Any] = {}
    for spec in vary:
        path, values = parse_vary(spec)
        if path in grid:
            raise StudyError(f"--vary {path}: given twice; give each field once")
        if is_condition(path):
            raise StudyError(
                f"--vary {path}: a condition of the plant, not something to buy (varying it "
                f"would buy the easiest); give it with --across {spec} "
                "so the choice must meet the target at every value"
            )
        grid[path] = values
    return grid


def check_design(
    scenario: Scenario,
    target: float,
    vary: Sequence[str],
    costs_file: Path | None = None,
    confidence: float = 0.95,
    first: int = 3,
    most: int = 24,
    trials: int = 30,
    across: Sequence[str] = (),
) -> tuple[dict[str, Any], dict[str, list[Any] | Continuous], list[dict[str, Any]]]:
    """Every check of a design's input, before anything is written: the costs, the varied
    fields, the conditions and the combinations of the discrete fields (a StudyError, one
    line, otherwise)."""
    if not 0 < target <= 100:
        raise StudyError(f"--target: {target:g} is not allowed; give a percentage in (0, 100]")
    if not 0 < confidence < 1:
        raise StudyError(f"--confidence: {confidence:g} is not allowed; give 0 < c < 1")
    if not 2 <= first <= most or most > MAX_REPLICATIONS:
        raise StudyError(
            f"--replications {first}, --max-replications {most}: not allowed; give "
            f"2 <= replications <= max-replications <= {MAX_REPLICATIONS}"
        )
    shifts = "feeder.trace" in parse_across(across, scenario)  # each shift's trace: a condition
    conditions = conditions_of(scenario, parse_across(across, scenario))
    if scenario.feeder.arrival == "trace" and len(trace_files(scenario)) < 2 and not shifts:
        raise StudyError(
            "design: one replayed trace is one sample, so no interval can say a configuration "
            "meets the target; give several traces (feeder.trace = a list or a folder) or add "
            "--set feeder.arrival=poisson (or normal) for random arrivals at its mean rate"
        )
    check_replications(scenario, most, "--max-replications")  # trace k in replication k
    costs = read_costs(costs_file)
    grid = parse_grid(vary)
    box = {p: r for p, r in grid.items() if isinstance(r, Continuous)}
    if box and not 2 <= trials <= 1000:
        raise StudyError(f"--trials: {trials} is not allowed; give 2 to 1000")
    discrete = {p: v for p, v in grid.items() if isinstance(v, list)}
    count = math.prod(len(v) for v in discrete.values()) * (trials if box else 1)
    if count > MAX_CONFIGURATIONS:
        raise StudyError(
            f"--vary: {count:,} configurations to try; at most {MAX_CONFIGURATIONS:,}: vary "
            "fewer fields or give fewer values"
        )
    combos = [dict(zip(discrete, c, strict=True)) for c in itertools.product(*discrete.values())]
    corners = [{p: getattr(r, end) for p, r in box.items()} for end in ("low", "high")]
    for values in combos:
        for corner in corners if box else [{}]:
            point = {**values, **corner}
            try:
                sc = with_overrides(scenario, point) if point else scenario
                for condition in conditions[1:]:
                    with_overrides(sc, condition)
            except ScenarioError as e:
                raise StudyError(f"--vary {point}: {e}") from None
            for path in box:
                if isinstance(_field(sc, path), int) and not isinstance(_field(sc, path), bool):
                    raise StudyError(
                        f"--vary {path}: a whole-number field; give LO:HI without decimal points"
                    )
            capital(costs, sc)  # a price for every robot and belt speed the search can reach
    return costs, grid, combos


def check_baseline(
    path: Path | None, costs_file: Path | None, scenario: Scenario, across: Sequence[str]
) -> Scenario | None:
    """Today's line (``--baseline FILE``), loaded and checked against the conditions before
    anything is written; None without one."""
    if path is None:
        return None
    if costs_file is None:
        raise StudyError(
            f"--baseline {path}: the saving is in lost parts; give --costs with lost_part_cost"
        )
    today = load_scenario(path)
    for condition in conditions_of(scenario, parse_across(across, scenario)):
        try:
            with_overrides(today, condition) if condition else today
        except ScenarioError as e:
            raise StudyError(f"--baseline {path} at --across {condition}: {e}") from None
    return today


def run_design(
    scenario: Scenario,
    out: Path,
    target: float,
    vary: Sequence[str],
    policies: Sequence[str] | None = None,
    costs_file: Path | None = None,
    confidence: float = 0.95,
    first: int = 3,
    most: int = 24,
    workers: int = 1,
    engine: str = "auto",
    command: str = "",
    progress: Callable[[int, int], None] | None = None,
    trials: int = 30,
    kpi: KpiChoice = GRIPPING,
    across: Sequence[str] = (),
    baseline: Scenario | None = None,
    executor: Executor | None = None,
) -> dict[str, Any]:
    """Find the cheapest configuration meeting ``target`` (see the module docstring) on
    the ``kpi`` figure (G by default) at every condition of ``across``: the rows' and the
    answer's ``gripping_rate``, ``ci_low`` and ``ci_high`` are that figure's (the worst
    condition's), which design.json's ``kpi`` names; the lost parts' cost stays on G. With a
    ``baseline`` (today's line) the answer adds the saving a year and the payback."""
    costs, grid, combos = check_design(
        scenario, target, vary, costs_file, confidence, first, most, trials, across
    )
    conditions = conditions_of(scenario, parse_across(across, scenario))
    t0 = time.perf_counter()
    box = {p: r for p, r in grid.items() if isinstance(r, Continuous)}
    rules = list(policies or [scenario.policy])
    asked = {"target": target, "confidence": confidence, "vary": grid, "first": first}
    asked |= {"most": most, "trials": trials}
    if across:  # conditions and today's line are part of the question (absent: as before)
        asked["across"] = conditions
    if baseline is not None:
        asked["baseline"] = baseline.model_dump(mode="json")
    question = question_key(scenario, asked, rules, costs, kpi)
    done = answered(Path(out) / SUMMARY_FILE, question)  # the same question, answered before
    if done is not None:
        done |= {"simulated": 0, "replayed": done["runs"], "command": command}
        done |= {"runs_simulated": 0, "runs_replayed": done["runs"]}
        done["wall_time"] = time.perf_counter() - t0
        write_json(done, Path(out) / SUMMARY_FILE, keep_nan=True)
        return done
    groups: list[tuple[dict[str, Any], str]] = [(v, rule) for v in combos for rule in rules]
    k = len(groups) * (trials if box else 1)
    level = 1.0 - (1.0 - confidence) / (k * looks(first, most) * len(conditions))
    seeds = replication_seeds(scenario.seed, most)
    counts = {"simulated": 0, "replayed": 0, "runs_simulated": 0, "runs_replayed": 0}
    configs: list[Config] = []
    store = RunStore(Path(out) / EVALS)  # one store for every batch: opened once
    known: dict[tuple[Any, ...], Config] = {}  # (rule, values): found at once, not searched
    met_cost: dict[Config, float] = {}  # each met configuration's total cost
    changed: set[Config] = set()  # configurations with new runs since best_met() looked
    unknown: set[Config] = set()  # met configurations whose total cost is NaN
    # the KPIs each run keeps (part of its journal key: G's runs serve G and, on a line
    # without kinds, the value rate; another figure's are its own)
    kept = ["part_flow"] + ([] if kpi.column == "gripping_rate" else [kpi.column])

    def cells(sc: Scenario) -> list[Cell]:
        return [Cell(c, with_overrides(sc, c) if c else sc) for c in conditions]

    def config(values: dict[str, Any], rule: str) -> Config:
        values = {p: values[p] for p in grid}  # the order the fields were given in
        try:
            found = known.get((rule, *values.items()))
        except TypeError:  # a value that is a list: searched
            found = next((c for c in configs if c.policy == rule and c.values == values), None)
        if found is not None:
            return found
        try:
            sc = with_overrides(scenario, values) if values else scenario
        except ScenarioError as e:
            raise StudyError(f"--vary {values}: {e}") from None
        c = Config(values, rule, cells(sc), capital(costs, sc), robot_prices(costs, sc))
        configs.append(c)
        try:
            known[(rule, *values.items())] = c
        except TypeError:
            pass
        return c

    def extend(todo: list[Config], n: int) -> None:
        for rule in dict.fromkeys([*rules, *(c.policy for c in todo)]):
            mine = [c for c in todo if c.policy == rule]
            for rep in range(min(len(c.g) for c in mine) if mine else n, n):
                need = [cell for c in mine if len(c.g) == rep for cell in c.cells]
                if not need:
                    continue
                names = [
                    c.label() + "".join(f", {p}={v}" for p, v in cell.condition.items())
                    for c in mine
                    if len(c.g) == rep
                    for cell in c.cells
                ]
                ev = Evaluator(out, [rule], [seeds[rep]], kept, workers, engine, store, executor)
                lines = [for_replication(cell.scenario, rep) for cell in need]  # trace k in rep k
                points = [
                    {**c.values, **cell.condition}
                    for c in mine
                    if len(c.g) == rep
                    for cell in c.cells
                ]
                rows = ev.runs(lines, names, points)
                changed.update(c for c in mine if len(c.g) == rep)
                for key in counts:
                    counts[key] += getattr(ev, key)
                counts["runs_replayed"] += ev.runs_from_points
                for cell, r in zip(need, rows, strict=True):
                    cell.g.append(float(r[rule][0]["gripping_rate"]))
                    cell.y.append(float(r[rule][0][kpi.column]))
                    cell.flow.append(float(r[rule][0]["part_flow"]))
        if progress is not None:
            progress(sum(len(c.g) for c in configs), k * most)

    def best_met() -> float:
        """The cheapest met configuration's total cost; only configurations with new runs
        are looked at again (looking at all at every point made a design quadratic)."""
        for c in changed:
            met_cost.pop(c, None)
            unknown.discard(c)
            if _state(c, level, target) == "met":
                met_cost[c] = c.capital + c.lost_cost(costs)
                if math.isnan(met_cost[c]):
                    unknown.add(c)
        changed.clear()
        if unknown:  # a NaN cost: the minimum then depends on the order, the configurations'
            return min((met_cost[c] for c in configs if c in met_cost), default=math.inf)
        return min(met_cost.values(), default=math.inf)

    def decide(c: Config) -> None:
        """Replications for one point, doubled while it is open and could be the cheapest."""
        extend([c], max(first, len(c.g)))
        while _state(c, level, target) == "open" and c.capital < best_met() and len(c.g) < most:
            extend([c], min(most, 2 * len(c.g)))

    if box:
        for i, (values, rule) in enumerate(groups):
            _optimise(
                box,
                trials,
                scenario.seed + 7919 * i,
                functools.partial(lambda v, r, point: config({**v, **point}, r), values, rule),
                decide,
                lambda c: (c.capital + c.lost_cost(costs), target - c.bounds(level)[1]),
            )
    else:
        for values, rule in groups:
            config(values, rule)
    extend(configs, first)
    rounds = [first]
    while True:
        state = {id(c): _state(c, level, target) for c in configs}
        best = best_met()
        # open configurations that could still beat the cheapest met one (capital alone)
        todo = [c for c in configs if state[id(c)] == "open" and c.capital < best]
        todo = [c for c in todo if len(c.g) < most]
        if not todo:
            break
        n = min(most, 2 * max(len(c.g) for c in todo))
        extend(todo, n)
        rounds.append(n)
    rows = [_row(c, level, target, costs, confidence) for c in configs]
    order = sorted(range(len(rows)), key=lambda i: rows[i]["total_cost"])
    met = [i for i in order if rows[i]["state"] == "met"]
    chosen = configs[met[0]] if met else None
    answer = rows[met[0]] if met else None
    alternatives = []
    for i in met[1:6]:
        alt = dict(rows[i])
        if chosen is not None:
            low, high = paired_lost_difference(chosen, configs[i], confidence)
            capital_diff = configs[i].capital - chosen.capital
            if float(costs["lost_part_cost"]) and float(costs["hours"]):
                alt["extra_low"] = capital_diff + running_per_part(costs) * low
                alt["extra_high"] = capital_diff + running_per_part(costs) * high
        alternatives.append(alt)
    result: dict[str, Any] = {
        "target": target,
        "confidence": confidence,
        **({} if kpi.default else {"kpi": kpi.to_json()}),
        "confidence_each": level,
        "configurations": k,
        "looks": looks(first, most),
        "evaluated": len(configs),
        "vary": {
            p: [v.low, v.high] if isinstance(v, Continuous) else list(v) for p, v in grid.items()
        },
        **({"across": parse_across(across, scenario), "conditions": conditions} if across else {}),
        "continuous": list(box),
        "trials": trials if box else None,
        "rules": rules,
        "costs": costs_json(costs),
        "cost_file": costs_file is not None,
        "choice": answer["choice"] if answer else None,
        "notes": line_notes(chosen.scenario, costs.get("owned") or ()) if chosen else [],
        "gripping_rate": answer["gripping_rate"] if answer else None,
        "ci_low": answer["ci_low"] if answer else None,
        "ci_high": answer["ci_high"] if answer else None,
        "replications": answer["replications"] if answer else None,
        "total_cost": answer["total_cost"] if answer else None,
        **(_money(chosen, answer, costs) if chosen is not None and answer else {}),
        "alternatives": alternatives,
        "rows": [rows[i] for i in order],
        "rounds": rounds,
        "replications_reached": sorted({len(c.g) for c in configs}),
        "runs": sum(r["replications"] for r in rows) * len(conditions),
        "runs_fixed": k * most * len(conditions),
        **counts,
        "seeds": seeds[: answer["replications"]] if answer else [],
        "scenario": scenario.model_dump(mode="json"),
        "scenario_chosen": chosen.scenario.model_dump(mode="json") if chosen else None,
        "scenario_name": scenario.name,
        "command": command,
        "question": question,  # design_answer: the same question asked again is read back
    }
    if baseline is not None and chosen is not None:
        base = Config({}, baseline.policy, cells(baseline), 0.0)
        extend([base], len(chosen.g))
        result["payback"] = payback(chosen, base, costs, confidence, level)
        result["payback_runs"] = len(base.g) * len(conditions)
    result["wall_time"] = time.perf_counter() - t0
    result["text"] = design_text(result, kpi)
    write_json(result, Path(out) / SUMMARY_FILE, keep_nan=True)
    return result


def _row(
    c: Config, level: float, target: float, costs: Mapping[str, Any], confidence: float
) -> dict[str, Any]:
    """One configuration's row of design.json."""
    mean, low, high = c.bounds(level)
    lost = c.lost_cost(costs)
    half = c.lost_cost_half_width(costs, confidence)
    return {
        "choice": {**c.values, "policy": c.policy},
        "gripping_rate": mean,
        "ci_low": low,
        "ci_high": high,
        "replications": len(c.g),
        "state": _state(c, level, target),
        "capital_cost": c.capital,
        "lost_parts_cost": lost,
        "total_cost": c.capital + lost,
        "total_cost_low": c.capital + max(0.0, lost - half),
        "total_cost_high": c.capital + lost + half,
        "robot_prices": c.prices,
    }


def _money(c: Config, row: Mapping[str, Any], costs: Mapping[str, Any]) -> dict[str, Any]:
    """The answer's cost apart: capital, running (lost parts), the interval of the total
    and the cost per part gripped over the cost file's hours."""
    parts = c.gripped_per_s() * SECONDS_PER_HOUR * float(costs["hours"])
    return {
        "capital_cost": c.capital,
        "running_cost": row["lost_parts_cost"],
        "total_cost_low": row["total_cost_low"],
        "total_cost_high": row["total_cost_high"],
        "robot_prices": c.prices,
        "cost_per_part": row["total_cost"] / parts if parts > 0 else None,
    }


def _optimise(
    box: Mapping[str, Continuous],
    trials: int,
    seed: int,
    config: Callable[[dict[str, float]], Config],
    decide: Callable[[Config], None],
    score: Callable[[Config], tuple[float, float]],
) -> None:
    """Optuna's constrained TPE over the continuous box for one combination of the discrete
    fields and rule: minimise the total cost subject to target - lower bound <= 0, in
    ``trials`` points (asked and told here, so each point runs through ``decide``)."""
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # constraints_func and multivariate are experimental
        sampler = optuna.samplers.TPESampler(
            seed=seed,
            n_startup_trials=max(2, min(10, trials // 3)),
            multivariate=len(box) > 1,
            constraints_func=lambda t: t.user_attrs["constraint"],
        )
        study = optuna.create_study(direction="minimize", sampler=sampler)
        for _ in range(trials):
            trial = study.ask()
            point = {
                p: min(r.high, max(r.low, round_value(trial.suggest_float(p, r.low, r.high))))
                for p, r in box.items()
            }
            c = config(point)
            decide(c)
            cost, gap = score(c)
            trial.set_user_attr("constraint", [gap])
            study.tell(trial, cost)


def _state(c: Config, level: float, target: float) -> str:
    _, low, high = c.bounds(level)
    if low >= target:
        return "met"
    if high < target:
        return "missed"
    return "open"
