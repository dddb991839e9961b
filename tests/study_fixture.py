"""Small but real study folders for report tests, made by the real study functions.

``make_study`` runs ``pnp_twin.studies.run_sweep``, ``run_size`` or ``run_mix`` on the
shipped baseline line with short runs, so a report test reads exactly what ``pnp-twin
sweep``, ``size`` and ``mix`` write (tables, records, meta.json, sizing.json, mix.json):
nothing here re-implements a summary, an interval or a sizing answer. Import it explicitly:
``from tests.study_fixture import make_study``.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies import Options, build_plan, run_sweep
from pnp_twin.studies.rulemix import run_mix
from pnp_twin.studies.sizing import run_size
from pnp_twin.twin import load_scenario

BASELINE = Path(__file__).resolve().parents[1] / "scenarios" / "paper_baseline.toml"


def make_study(
    folder: Path,
    grid: Mapping[str, Sequence[Any]] | None = None,
    policies: Sequence[str] = ("SD", "FIFO"),
    replications: int = 2,
    duration: float = 60.0,
    warmup: float = 10.0,
    kind: str = "sweep",
    records: bool = True,
    target: float = 90.0,
    master_seed: int = 7,
    base: Mapping[str, Any] | None = None,
) -> Path:
    """Run a ``kind`` study (sweep, size or mix) into ``folder``; returns ``folder``.

    ``policies`` are the policies compared (sweep, size) or the rules mixed (mix);
    ``records=False`` removes the recorded run afterwards, as an older study may lack it.
    """
    grid = {k: list(v) for k, v in (grid or {}).items()}
    sweep = {"grid": grid, "duration": duration, "warmup": warmup}
    overrides = {"seed": master_seed, **(base or {}), "sweep": sweep}
    scenario = load_scenario(BASELINE, overrides=overrides)
    command = f"pnp-twin {kind} {BASELINE.stem} --out {folder.name}"
    options = Options(workers=1, command=command)
    if kind == "sweep":
        plan = build_plan(scenario, policies=list(policies), replications=replications)
        run_sweep(plan, folder, options)
    elif kind == "size":
        run_size(scenario, folder, target, options, list(policies), replications)
    elif kind == "mix":
        run_mix(scenario, folder, options, list(policies), replications)
    else:
        raise ValueError(f"kind: {kind!r}; allowed sweep, size, mix")
    if not records:
        shutil.rmtree(folder / "records")
    return folder
