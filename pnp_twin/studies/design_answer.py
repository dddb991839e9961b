"""A finished design asked the same question again: its answer read back, not searched again.

Every run of a design is in the runs store, but replaying optuna's search over thousands of
points still takes its own time (a 3,000-point design: about 15 s of TPE sampling, with no
run simulated). The search is deterministic, so the same question on the same folder has the
same answer: ``design.json`` keeps the hash of its question (:func:`question_key`: the
resolved scenario, target, confidence, figure, varied fields, rules, prices as read,
replications, trials, and the source of the code that answers), and :func:`answered` returns
it when asked again. Any change (another target, a cost file with another price, a changed
design module) is another question, answered by a search whose runs come from the store.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies.kpi_choice import KpiChoice
from pnp_twin.twin import __version__
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

CODE = (
    "pnp_twin.studies.design",
    "pnp_twin.studies.design_config",
    "pnp_twin.studies.design_conditions",
    "pnp_twin.studies.design_text",
    "pnp_twin.studies.prices",
    "pnp_twin.studies.calibrate_eval",
    __name__,
)


def question_key(
    scenario: Scenario,
    settings: Mapping[str, Any],
    rules: Sequence[str],
    costs: Mapping[str, Any],
    kpi: KpiChoice,
) -> str:
    """The hash of everything a design's answer depends on; ``settings`` holds the target,
    confidence, varied fields, replications and trials as the design read them."""
    what = {
        "scenario": scenario.model_dump(mode="json"),
        "settings": dict(settings),
        "rules": list(rules),
        "costs": costs,
        "kpi": kpi.name,
        "code": [__version__, *(_source_digest(m) for m in CODE)],
    }
    text = json.dumps(what, sort_keys=True, default=repr)
    return hashlib.sha1(text.encode()).hexdigest()


def _source_digest(module: str) -> str:
    path = getattr(sys.modules.get(module), "__file__", None)
    try:
        return hashlib.sha1(Path(str(path)).read_bytes()).hexdigest() if path else ""
    except OSError:
        return ""


def answered(path: Path, key: str) -> dict[str, Any] | None:
    """The answer ``path`` (a finished ``design.json``) holds for the question ``key``; None
    when there is none, it is another question's or it cannot be read."""
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict) or data.get("question") != key:
        return None
    if not isinstance(data.get("runs"), int) or not isinstance(data.get("text"), str):
        return None
    log.info("%s: the same question, answered before; read back", path)
    return data
