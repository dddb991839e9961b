"""The cost file of ``design`` (and ``--costs`` of ``sweep``, ``size``, ``mix``): what a line
costs to buy and to run.

The file is TOML::

    robot_price = 25000            # per robot; or a table keyed by arm speed in m/s:
    # [robot_price]  "2.0" = 20000   "4.0" = 25000   "6.0" = 32000
    belt_price = 8000              # one number, or a table keyed by belt speed in m/s
    lost_part_cost = 0.05          # per part that reaches the return conveyor
    hours = 4000                   # operating hours the lost parts are counted over
    owned = [2, 3]                 # optional: robots already owned (priced 0, still counted)
    hours_per_year = 4000          # optional: operating hours a year (payback; default hours)

Every robot is priced at its own arm speed (``robots.overrides`` included); a speed between
two listed ones is priced by linear interpolation, a speed outside them is refused. The file
is read through :func:`pnp_twin.twin.inputs.read_user_text` (a regular file, at most
``COSTS_BYTES``, UTF-8), and every number is checked: finite, at least 0, at most
:data:`MAX_NUMBER`; speed keys are positive speeds, each listed once ("3" and "3.0" are the
same speed).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.errors import excerpt
from pnp_twin.twin.inputs import COSTS_BYTES, read_user_text
from pnp_twin.twin.scenario import Scenario

COST_KEYS = ("robot_price", "belt_price", "lost_part_cost", "hours")
OPTIONAL_KEYS = ("owned", "hours_per_year")
SECONDS_PER_HOUR = 3600.0
MAX_NUMBER = 1e12  # a price, cost or number of hours above this is a typo (1e308 overflows)
MAX_SPEED = 100.0  # m/s: a price table's keys
MAX_ROBOT = 64  # robots.count's bound


def _number(value: Any, key: str, where: str, most: float = MAX_NUMBER) -> float:
    """One finite number in [0, most], or a one-line StudyError naming the key and value."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise StudyError(
            f"{where}: {key} = {excerpt(value)} is not allowed; give a number from 0 to {most:g}"
        )
    if not math.isfinite(value) or not 0 <= value <= most:
        raise StudyError(
            f"{where}: {key} = {excerpt(float(value))} is not allowed; give a number from 0 "
            f"to {most:g}"
        )
    return float(value)


def _speed(text: str, key: str, where: str) -> float:
    try:
        speed = float(text)
    except ValueError:
        speed = math.nan
    if not (math.isfinite(speed) and 0 < speed <= MAX_SPEED):
        raise StudyError(
            f"{where}: {key}: speed {excerpt(text)} is not allowed; give a speed in m/s above "
            f'0 and at most {MAX_SPEED:g}, e.g. "2.0"'
        )
    return speed


def _priced(value: Any, key: str, where: str) -> float | dict[float, float]:
    """A price: one number, or a table {speed in m/s: price} with each speed once."""
    if isinstance(value, dict):
        if not value:
            raise StudyError(f"{where}: {key} is an empty table; give at least one speed")
        table: dict[float, float] = {}
        names: dict[float, str] = {}
        for text, price in value.items():
            speed = _speed(str(text), key, where)
            if speed in table:
                raise StudyError(
                    f'{where}: {key}: speeds "{names[speed]}" and "{text}" are the same '
                    f"{speed:g} m/s; list each speed once"
                )
            table[speed] = _number(price, f'{key}."{text}"', where)
            names[speed] = str(text)
        return table
    if isinstance(value, int | float) and not isinstance(value, bool):
        return _number(value, key, where)
    raise StudyError(
        f"{where}: {key} = {excerpt(value)} is not allowed; give a number or a table keyed by "
        "speed in m/s"
    )


def _owned(value: Any, where: str) -> list[int]:
    ok = isinstance(value, list) and all(
        isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_ROBOT for v in value
    )
    if not ok or len(set(value)) != len(value):
        raise StudyError(
            f"{where}: owned = {excerpt(value)} is not allowed; give robot numbers from 1 to "
            f"{MAX_ROBOT}, each once, e.g. owned = [2, 3]"
        )
    return sorted(value)


def read_costs(path: Path | None) -> dict[str, Any]:
    """The cost file (see the module docstring); without one, robots and belts cost 1 and
    lost parts nothing (the cheapest configuration is then the one with fewest robots)."""
    if path is None:
        return {"robot_price": 1.0, "belt_price": 0.0, "lost_part_cost": 0.0, "hours": 0.0}
    where = f"--costs {path}"
    text = read_user_text(Path(path), "--costs", COSTS_BYTES, StudyError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{where}: not valid TOML ({str(e).splitlines()[0]})") from None
    allowed = COST_KEYS + OPTIONAL_KEYS
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise StudyError(f"{where}: unknown key {unknown[0]}; allowed {', '.join(allowed)}")
    missing = [k for k in COST_KEYS if k not in data]
    if missing:
        raise StudyError(f"{where}: {missing[0]} is missing; give {', '.join(COST_KEYS)}")
    out: dict[str, Any] = {k: _priced(data[k], k, where) for k in ("robot_price", "belt_price")}
    for k in ("lost_part_cost", "hours"):
        if isinstance(data[k], dict):
            raise StudyError(f"{where}: {k} is a table; give one number")
        out[k] = _number(data[k], k, where, 24 * 366 * 100 if k == "hours" else MAX_NUMBER)
    if "owned" in data:
        out["owned"] = _owned(data["owned"], where)
    if "hours_per_year" in data:
        out["hours_per_year"] = _number(data["hours_per_year"], "hours_per_year", where, 24 * 366)
    return out


def costs_json(costs: Mapping[str, Any]) -> dict[str, Any]:
    """The cost file's values as JSON (price tables keyed by speed text)."""
    return {
        k: (v if not isinstance(v, dict) else {f"{s:g}": p for s, p in v.items()})
        for k, v in costs.items()
    }


def price_at(price: float | dict[float, float], speed: float, key: str, what: str = "") -> float:
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
    known = ", ".join(f"{s:g}" for s in sorted(price))
    raise StudyError(
        f"--costs: {key} has no price for {speed:g} m/s{what}; priced {known} m/s (a speed "
        "between two of them is interpolated): add the speed to the table"
    )


def robot_prices(costs: Mapping[str, Any], sc: Scenario) -> list[float]:
    """Each robot's price, robot 1 first: at its own arm speed (an override's where set),
    0 for a robot the cost file lists as ``owned``."""
    owned = set(costs.get("owned") or ())
    prices = []
    for i in range(1, sc.robots.count + 1):
        if i in owned:
            prices.append(0.0)
            continue
        speed = float(sc.robots.param(i, "arm_speed"))
        what = f" (robot {i}'s arm speed)" if sc.robots.overrides else ""
        prices.append(price_at(costs["robot_price"], speed, "robot_price", what))
    return prices


def capital(costs: Mapping[str, Any], sc: Scenario) -> float:
    """Robots and belt: what the configuration costs to buy (owned robots at 0)."""
    belt = price_at(costs["belt_price"], sc.belt.speed, "belt_price")
    return math.fsum(robot_prices(costs, sc)) + belt  # fsum: n equal prices give n x price


def running_per_part(costs: Mapping[str, Any]) -> float:
    """What one lost part per second costs over the cost file's hours."""
    return float(costs["lost_part_cost"]) * SECONDS_PER_HOUR * float(costs["hours"])
