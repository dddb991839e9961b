"""``--vary PATH=...`` of ``design`` and ``capacity`` (and ``--across``'s values): a list, a
range of whole numbers, or a continuous range (a bound written with a decimal point)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pnp_twin.studies.plan import StudyError, field_path_error
from pnp_twin.twin.loader import parse_value

DIGITS = 4  # continuous values are rounded to 4 significant digits (reused across questions)


@dataclass(frozen=True)
class Continuous:
    """A continuous range LO:HI (written with a decimal point), searched by the optimiser."""

    low: float
    high: float


def round_value(x: float) -> float:
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
