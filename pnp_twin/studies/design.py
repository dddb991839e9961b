"""Design: the cheapest configuration whose gripping rate meets a target with a confidence.

The configurations are every combination of the varied fields (``--vary PATH=LO:HI`` for a
range of whole numbers, ``--vary PATH=V1,V2,...`` for a list) and the rules. Each one's total
cost of ownership comes from a cost file (TOML)::

    robot_price = 25000            # per robot; or a table keyed by arm speed in m/s:
    # [robot_price]  "2.0" = 20000   "4.0" = 25000   "6.0" = 32000
    belt_price = 8000              # one number, or a table keyed by belt speed in m/s
    lost_part_cost = 0.05          # per part that reaches the return conveyor
    hours = 4000                   # operating hours the lost parts are counted over

total cost = robots x robot price (at the arm speed) + belt price (at the belt speed) +
lost_part_cost x (part flow x (1 - G)) x 3600 x hours, with G the mean gripping rate.

Selection with a confidence that holds after it: every configuration's interval of G is
taken at the Bonferroni level 1 - (1 - c) / K over the K configurations, so all intervals
hold together with confidence c and the pick among them keeps it. The procedure is
sequential: every configuration gets ``first`` replications (common random numbers:
replication k has the same seed everywhere); a configuration is *met* when its lower bound
reaches the target, *missed* when its upper bound is below it, *open* otherwise; while an
open configuration could still be cheaper than the cheapest met one, the open ones that
could are doubled in replications (up to ``most``), nowhere else. Every run is journalled
per configuration, rule and seed under ``DIR/evals/``, so asking again with another target,
confidence or cost file simulates only the replications the new question needs.
"""

from __future__ import annotations

import itertools
import math
import time
import tomllib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies.calibrate_eval import Evaluator
from pnp_twin.studies.plan import StudyError, field_path_error
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import ScenarioError, parse_value, with_overrides
from pnp_twin.twin.output import write_json
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

SUMMARY_FILE = "design.json"
COST_KEYS = ("robot_price", "belt_price", "lost_part_cost", "hours")
SECONDS_PER_HOUR = 3600.0


def parse_vary(spec: str) -> tuple[str, list[Any]]:
    """'robots.count=4:9' -> (path, [4, ..., 9]); 'robots.arm_speed=3,4,5' -> a list."""
    path, sep, text = spec.partition("=")
    path = path.strip()
    if not sep or not path or not text.strip():
        raise StudyError(f"--vary {spec!r}: give PATH=LO:HI or PATH=V1,V2,...")
    problem = field_path_error(path)
    if problem:
        raise StudyError(problem.replace("sweep.grid", "--vary"))
    if ":" in text:
        lo_text, _, hi_text = text.partition(":")
        try:
            lo, hi = int(lo_text), int(hi_text)
        except ValueError:
            raise StudyError(
                f"--vary {spec}: a range LO:HI is of whole numbers (give a list V1,V2,... "
                "for other values)"
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
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as e:
        raise StudyError(f"{where}: cannot read ({e.strerror or type(e).__name__})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
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
    if not isinstance(price, dict):
        return price
    for s, p in price.items():
        if math.isclose(s, speed, rel_tol=1e-9):
            return p
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
        self.g: list[float] = []
        self.flow: list[float] = []

    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.values.items()) + f", {self.policy}"

    def bounds(self, level: float) -> tuple[float, float, float]:
        mean, low, high = t_interval(self.g, level)
        low = max(low, 0.0) if math.isfinite(low) else 0.0
        high = min(high, 100.0) if math.isfinite(high) else 100.0
        return mean, low, high

    def lost_cost(self, costs: Mapping[str, Any]) -> float:
        if not self.g:
            return math.nan
        mean_g = sum(self.g) / len(self.g)
        flow = sum(self.flow) / len(self.flow)
        lost_per_s = flow * (1.0 - mean_g / 100.0)
        return float(costs["lost_part_cost"]) * lost_per_s * SECONDS_PER_HOUR * costs["hours"]


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
) -> dict[str, Any]:
    """Find the cheapest configuration meeting ``target`` (see the module docstring)."""
    if not 0 < target <= 100:
        raise StudyError(f"--target: {target:g} is not allowed; give a percentage in (0, 100]")
    if not 0 < confidence < 1:
        raise StudyError(f"--confidence: {confidence:g} is not allowed; give 0 < c < 1")
    if not 2 <= first <= most:
        raise StudyError(f"--replications: {first} (at most {most}) is not allowed; give >= 2")
    t0 = time.perf_counter()
    costs = read_costs(costs_file)
    grid = dict(parse_vary(v) for v in vary)
    rules = list(policies or [scenario.policy])
    configs = []
    for combo in itertools.product(*grid.values()):
        values = dict(zip(grid, combo, strict=True))
        try:
            sc = with_overrides(scenario, values) if values else scenario
        except ScenarioError as e:
            raise StudyError(f"--vary {values}: {e}") from None
        for rule in rules:
            configs.append(Config(values, rule, sc, capital(costs, sc)))
    k = len(configs)
    level = 1.0 - (1.0 - confidence) / k
    seeds = replication_seeds(scenario.seed, most)
    simulated = replayed = 0

    def extend(todo: list[Config], n: int) -> None:
        nonlocal simulated, replayed
        for rule in rules:
            mine = [c for c in todo if c.policy == rule]
            for rep in range(min(len(c.g) for c in mine) if mine else n, n):
                need = [c for c in mine if len(c.g) == rep]
                if not need:
                    continue
                ev = Evaluator(out, [rule], [seeds[rep]], ["part_flow"], workers, engine)
                rows = ev.runs([c.scenario for c in need], [c.label() for c in need])
                simulated += ev.simulated
                replayed += ev.replayed
                for c, r in zip(need, rows, strict=True):
                    c.g.append(float(r[rule][0]["gripping_rate"]))
                    c.flow.append(float(r[rule][0]["part_flow"]))
        if progress is not None:
            progress(sum(len(c.g) for c in configs), k * most)

    extend(configs, first)
    rounds = [first]
    while True:
        state = {id(c): _state(c, level, target) for c in configs}
        met = [c for c in configs if state[id(c)] == "met"]
        best = min((c.capital + c.lost_cost(costs) for c in met), default=math.inf)
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
        "confidence_each": level,
        "configurations": k,
        "vary": {p: list(v) for p, v in grid.items()},
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
    }
    result["text"] = design_text(result)
    write_json(result, Path(out) / SUMMARY_FILE, keep_nan=True)
    return result


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


def design_text(d: dict[str, Any]) -> str:
    """The answer in one sentence, with the next best for how much more."""
    conf = f"{100 * d['confidence']:g} %"
    if d["choice"] is None:
        return (
            f"No configuration of the {d['configurations']} tried meets G ≥ {d['target']:g} % "
            f"with {conf} confidence (after selecting among them)."
        )
    out = (
        f"{choice_text(d['choice'])}: G = {d['gripping_rate']:.1f} % "
        f"[{d['ci_low']:.1f}, {d['ci_high']:.1f}] meets G ≥ {d['target']:g} % with {conf} "
        f"confidence after selecting among {d['configurations']} configurations; total cost "
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
