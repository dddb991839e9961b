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
import tomllib
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pnp_twin.studies.calibrate_eval import EVALS, Evaluator
from pnp_twin.studies.design_answer import answered, question_key
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.studies.plan import StudyError, field_path_error
from pnp_twin.studies.runstore import RunStore
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.inputs import COSTS_BYTES, read_user_text
from pnp_twin.twin.loader import ScenarioError, parse_value, with_overrides
from pnp_twin.twin.output import write_json
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval
from pnp_twin.twin.trace import check_replications, for_replication, trace_files

SUMMARY_FILE = "design.json"
COST_KEYS = ("robot_price", "belt_price", "lost_part_cost", "hours")
SECONDS_PER_HOUR = 3600.0
DIGITS = 4  # continuous values are rounded to 4 significant digits (reused across questions)


@dataclass(frozen=True)
class Continuous:
    """A continuous range LO:HI (written with a decimal point), searched by the optimiser."""

    low: float
    high: float


def _round(x: float) -> float:
    return float(f"{x:.{DIGITS}g}")


def parse_vary(spec: str) -> tuple[str, list[Any] | Continuous]:
    """'robots.count=4:9' -> (path, [4, ..., 9]); 'robots.arm_speed=3,4,5' -> a list;
    'robots.arm_speed=2.0:6.0' (a bound with a decimal point) -> a Continuous range."""
    path, sep, text = spec.partition("=")
    path = path.strip()
    if not sep or not path or not text.strip():
        raise StudyError(f"--vary {spec!r}: give PATH=LO:HI or PATH=V1,V2,...")
    problem = field_path_error(path)
    if problem:
        raise StudyError(problem.replace("sweep.grid", "--vary"))
    if ":" in text:
        lo_text, _, hi_text = text.partition(":")
        if "." in lo_text or "." in hi_text:
            try:
                a, b = float(lo_text), float(hi_text)
            except ValueError:
                raise StudyError(f"--vary {spec}: LO:HI must be two numbers") from None
            if not (math.isfinite(a) and math.isfinite(b)) or not a < b:
                raise StudyError(f"--vary {spec}: a continuous range needs LO < HI")
            return path, Continuous(a, b)
        try:
            lo, hi = int(lo_text), int(hi_text)
        except ValueError:
            raise StudyError(
                f"--vary {spec}: LO:HI is a range of whole numbers, or a continuous range "
                "when written with a decimal point (2.0:6.0)"
            ) from None
        if hi < lo or hi - lo > 200:
            raise StudyError(f"--vary {spec}: give LO <= HI, at most 200 apart")
        return path, list(range(lo, hi + 1))
    values = [parse_value(v.strip()) for v in text.split(",") if v.strip()]
    if not values:
        raise StudyError(f"--vary {spec}: no values")
    return path, list(dict.fromkeys(values))


def _priced(value: Any, key: str, where: str) -> float | dict[float, float]:
    if isinstance(value, bool):
        raise StudyError(f"{where}: {key} = {value} is not a price")
    if isinstance(value, int | float):
        if not math.isfinite(value) or value < 0:
            raise StudyError(f"{where}: {key} = {value} must be a number >= 0")
        return float(value)
    if isinstance(value, dict) and value:
        table = {}
        for speed, price in value.items():
            try:
                one = _priced(price, f"{key}.{speed}", where)
                if isinstance(one, dict):
                    raise StudyError(f"{where}: {key}.{speed} must be one number")
                table[float(speed)] = one
            except ValueError:
                raise StudyError(f"{where}: {key}: '{speed}' is not a speed in m/s") from None
        return table
    raise StudyError(f"{where}: {key} must be a number or a table keyed by speed in m/s")


def read_costs(path: Path | None) -> dict[str, Any]:
    """The cost file (see the module docstring); without one, robots and belts cost 1 and
    lost parts nothing (the cheapest configuration is then the one with fewest robots)."""
    if path is None:
        return {"robot_price": 1.0, "belt_price": 0.0, "lost_part_cost": 0.0, "hours": 0.0}
    where = f"--costs {path}"
    text = read_user_text(path, "--costs", COSTS_BYTES, StudyError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{where}: not valid TOML ({str(e).splitlines()[0]})") from None
    unknown = sorted(set(data) - set(COST_KEYS))
    if unknown:
        raise StudyError(f"{where}: unknown key {unknown[0]}; allowed {', '.join(COST_KEYS)}")
    missing = [k for k in COST_KEYS if k not in data]
    if missing:
        raise StudyError(f"{where}: {missing[0]} is missing; give {', '.join(COST_KEYS)}")
    out: dict[str, Any] = {k: _priced(data[k], k, where) for k in ("robot_price", "belt_price")}
    for k in ("lost_part_cost", "hours"):
        v = _priced(data[k], k, where)
        if isinstance(v, dict):
            raise StudyError(f"{where}: {k} must be one number")
        out[k] = v
    return out


def _price(price: float | dict[float, float], speed: float, key: str) -> float:
    """The price at ``speed``: a listed speed's, else interpolated linearly between the two
    listed speeds around it (a speed outside the listed ones has no price)."""
    if not isinstance(price, dict):
        return price
    for s, p in price.items():
        if math.isclose(s, speed, rel_tol=1e-9):
            return p
    below = [s for s in price if s < speed]
    above = [s for s in price if s > speed]
    if below and above:
        a, b = max(below), min(above)
        return price[a] + (price[b] - price[a]) * (speed - a) / (b - a)
    known = ", ".join(f"{s:g}" for s in price)
    raise StudyError(f"--costs: {key} has no price for {speed:g} m/s; priced: {known}")


def capital(costs: Mapping[str, Any], sc: Scenario) -> float:
    """Robots and belt: what the configuration costs to buy."""
    robots = sc.robots.count * _price(costs["robot_price"], sc.robots.arm_speed, "robot_price")
    return robots + _price(costs["belt_price"], sc.belt.speed, "belt_price")


class Config:
    """One configuration: its values, rule, scenario, cost and runs so far."""

    def __init__(self, values: dict[str, Any], policy: str, scenario: Scenario, cost: float):
        self.values = values
        self.policy = policy
        self.scenario = scenario
        self.capital = cost
        self.g: list[float] = []  # the gripping rate per replication (the lost parts' cost)
        self.y: list[float] = []  # the figure the target is on (--kpi; G by default)
        self.flow: list[float] = []
        self._bounds: dict[tuple[float, int], tuple[float, float, float]] = {}

    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.values.items()) + f", {self.policy}"

    def bounds(self, level: float) -> tuple[float, float, float]:
        # kept per count of runs (runs are only ever appended): a design asks every
        # configuration's bounds at each point, thousands of times over
        key = (level, len(self.y))
        if key not in self._bounds:
            mean, low, high = t_interval(self.y, level)
            low = max(low, 0.0) if math.isfinite(low) else 0.0
            high = min(high, 100.0) if math.isfinite(high) else 100.0
            self._bounds[key] = mean, low, high
        return self._bounds[key]

    def lost_cost(self, costs: Mapping[str, Any]) -> float:
        if not self.g:
            return math.nan
        mean_g = sum(self.g) / len(self.g)
        flow = sum(self.flow) / len(self.flow)
        lost_per_s = flow * (1.0 - mean_g / 100.0)
        return float(costs["lost_part_cost"]) * lost_per_s * SECONDS_PER_HOUR * costs["hours"]


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
    """``--vary`` options as {path: values or range}; a path given twice is refused."""
    grid: dict[str, Any] = {}
    for spec in vary:
        path, values = parse_vary(spec)
        if path in grid:
            raise StudyError(f"--vary {path}: given twice; give each field once")
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
) -> tuple[dict[str, Any], dict[str, list[Any] | Continuous], list[dict[str, Any]]]:
    """Every check of a design's input, before anything is written: the costs, the varied
    fields and the combinations of the discrete ones (a StudyError, one line, otherwise)."""
    if not 0 < target <= 100:
        raise StudyError(f"--target: {target:g} is not allowed; give a percentage in (0, 100]")
    if not 0 < confidence < 1:
        raise StudyError(f"--confidence: {confidence:g} is not allowed; give 0 < c < 1")
    if not 2 <= first <= most or most > MAX_REPLICATIONS:
        raise StudyError(
            f"--replications {first}, --max-replications {most}: not allowed; give "
            f"2 <= replications <= max-replications <= {MAX_REPLICATIONS}"
        )
    if scenario.feeder.arrival == "trace" and len(trace_files(scenario)) < 2:
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
            except ScenarioError as e:
                raise StudyError(f"--vary {point}: {e}") from None
            for path in box:
                if isinstance(_field(sc, path), int) and not isinstance(_field(sc, path), bool):
                    raise StudyError(
                        f"--vary {path}: a whole-number field; give LO:HI without decimal points"
                    )
            capital(costs, sc)  # a price for every speed the search can reach
    return costs, grid, combos


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
) -> dict[str, Any]:
    """Find the cheapest configuration meeting ``target`` (see the module docstring) on
    the ``kpi`` figure (G by default): the rows' and the answer's ``gripping_rate``,
    ``ci_low`` and ``ci_high`` are that figure's, which design.json's ``kpi`` names; the lost
    parts' cost stays on G."""
    costs, grid, combos = check_design(
        scenario, target, vary, costs_file, confidence, first, most, trials
    )
    t0 = time.perf_counter()
    box = {p: r for p, r in grid.items() if isinstance(r, Continuous)}
    rules = list(policies or [scenario.policy])
    asked = {"target": target, "confidence": confidence, "vary": grid, "first": first}
    question = question_key(scenario, {**asked, "most": most, "trials": trials}, rules, costs, kpi)
    done = answered(Path(out) / SUMMARY_FILE, question)  # the same question, answered before
    if done is not None:
        done |= {"simulated": 0, "replayed": done["runs"], "command": command}
        done["wall_time"] = time.perf_counter() - t0
        write_json(done, Path(out) / SUMMARY_FILE, keep_nan=True)
        return done
    groups: list[tuple[dict[str, Any], str]] = [(v, rule) for v in combos for rule in rules]
    k = len(groups) * (trials if box else 1)
    level = 1.0 - (1.0 - confidence) / (k * looks(first, most))
    seeds = replication_seeds(scenario.seed, most)
    store = RunStore(Path(out) / EVALS)  # one store for every batch: opened once
    simulated = replayed = 0
    configs: list[Config] = []
    # the KPIs each run keeps (part of its journal key: G's runs serve G and, on a line
    # without kinds, the value rate; another figure's are its own)
    kept = ["part_flow"] + ([] if kpi.column == "gripping_rate" else [kpi.column])

    known: dict[tuple[Any, ...], Config] = {}  # (rule, values): found at once, not searched
    met_cost: dict[Config, float] = {}  # each met configuration's total cost
    changed: set[Config] = set()  # configurations with new runs since best_met() looked
    unknown: set[Config] = set()  # met configurations whose total cost is NaN

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
        c = Config(values, rule, sc, capital(costs, sc))
        configs.append(c)
        try:
            known[(rule, *values.items())] = c
        except TypeError:
            pass
        return c

    def extend(todo: list[Config], n: int) -> None:
        nonlocal simulated, replayed
        for rule in rules:
            mine = [c for c in todo if c.policy == rule]
            for rep in range(min(len(c.g) for c in mine) if mine else n, n):
                need = [c for c in mine if len(c.g) == rep]
                if not need:
                    continue
                ev = Evaluator(out, [rule], [seeds[rep]], kept, workers, engine, store)
                lines = [for_replication(c.scenario, rep) for c in need]  # trace k in rep k
                rows = ev.runs(lines, [c.label() for c in need], [c.values for c in need])
                simulated += ev.simulated
                replayed += ev.replayed
                for c, r in zip(need, rows, strict=True):
                    c.g.append(float(r[rule][0]["gripping_rate"]))
                    c.y.append(float(r[rule][0][kpi.column]))
                    c.flow.append(float(r[rule][0]["part_flow"]))
                    changed.add(c)
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
    rows: list[dict[str, Any]] = []
    for c in configs:
        mean, low, high = c.bounds(level)
        lost = c.lost_cost(costs)
        rows.append(
            {
                "choice": {**c.values, "policy": c.policy},
                "gripping_rate": mean,
                "ci_low": low,
                "ci_high": high,
                "replications": len(c.g),
                "state": _state(c, level, target),
                "capital_cost": c.capital,
                "lost_parts_cost": lost,
                "total_cost": c.capital + lost,
            }
        )
    feasible = sorted((r for r in rows if r["state"] == "met"), key=lambda r: r["total_cost"])
    answer = feasible[0] if feasible else None
    result: dict[str, Any] = {
        "target": target,
        "confidence": confidence,
        **({} if kpi.default else {"kpi": kpi.to_json()}),
        "confidence_each": level,
        "configurations": k,
        "evaluated": len(configs),
        "vary": {
            p: [v.low, v.high] if isinstance(v, Continuous) else list(v) for p, v in grid.items()
        },
        "continuous": list(box),
        "trials": trials if box else None,
        "rules": rules,
        "costs": {
            k2: (v if not isinstance(v, dict) else {f"{s:g}": p for s, p in v.items()})
            for k2, v in costs.items()
        },
        "choice": answer["choice"] if answer else None,
        "gripping_rate": answer["gripping_rate"] if answer else None,
        "ci_low": answer["ci_low"] if answer else None,
        "ci_high": answer["ci_high"] if answer else None,
        "total_cost": answer["total_cost"] if answer else None,
        "alternatives": feasible[1:6],
        "rows": sorted(rows, key=lambda r: r["total_cost"]),
        "rounds": rounds,
        "runs": sum(r["replications"] for r in rows),
        "runs_fixed": k * most,
        "simulated": simulated,
        "replayed": replayed,
        "scenario": scenario.model_dump(mode="json"),
        "scenario_name": scenario.name,
        "command": command,
        "wall_time": time.perf_counter() - t0,
        "question": question,  # design_answer: the same question asked again is read back
    }
    result["text"] = design_text(result, kpi)
    write_json(result, Path(out) / SUMMARY_FILE, keep_nan=True)
    return result


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
                p: min(r.high, max(r.low, _round(trial.suggest_float(p, r.low, r.high))))
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


def choice_text(choice: Mapping[str, Any]) -> str:
    """'6 robots, arm 4 m/s, running SPT' from a choice mapping."""
    words = []
    for path, value in choice.items():
        if path == "policy":
            continue
        if path == "robots.count":
            words.append(f"{value} robots")
        else:
            unit = {"arm_speed": " m/s", "speed": " m/s", "rate": " parts/s"}
            name = path.rsplit(".", 1)[-1]
            words.append(
                f"{name.replace('_', ' ')} {value:g}{unit.get(name, '')}"
                if isinstance(value, int | float)
                else f"{name} {value}"
            )
    return ", ".join(words) + f" running {choice.get('policy')}"


def design_text(d: dict[str, Any], kpi: KpiChoice = GRIPPING) -> str:
    """The answer in one sentence (on the ``kpi`` figure), with the next best for how much
    more."""
    conf = f"{100 * d['confidence']:g} %"
    k, n = d["configurations"], d.get("evaluated", d["configurations"])
    among = f"{k} configurations" if n == k else f"the {n} points evaluated (of {k} allowed)"
    if d["choice"] is None:
        return (
            f"No configuration of the {n} tried meets {kpi.short} ≥ {d['target']:g} % "
            f"with {conf} confidence (after selecting among them)."
        )
    out = (
        f"{choice_text(d['choice'])}: {kpi.short} = {d['gripping_rate']:.1f} % "
        f"[{d['ci_low']:.1f}, {d['ci_high']:.1f}] meets {kpi.short} ≥ {d['target']:g} % "
        f"with {conf} confidence after selecting among {among}; total cost "
        f"{d['total_cost']:,.0f}"
    )
    other = [
        a
        for a in d["alternatives"]
        if {k: v for k, v in a["choice"].items() if k != "policy"}
        != {k: v for k, v in d["choice"].items() if k != "policy"}
    ]
    if other:
        a = other[0]
        out += (
            f"; {choice_text(a['choice'])} also meets it for "
            f"{a['total_cost'] - d['total_cost']:,.0f} more"
        )
    return out + "."
