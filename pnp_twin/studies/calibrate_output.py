"""A calibration's outputs in its folder, each written atomically.

- ``scenario.toml``: the input scenario file with ``--set`` and the fitted values applied,
  headed by comments saying what was fitted, to what, the residuals, the command and the date;
- ``points.csv``: every point and KPI: target, predicted, 95 % CI, residual, weight, policy;
- ``profile.csv``: the objective along each parameter (and over each pair) near the optimum;
- ``curve.csv``: the fitted response across each varied field;
- ``calibration.json``: all of it in one object, which ``reports.calibration`` draws.
"""

from __future__ import annotations

import datetime as dt
import math
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pnp_twin.studies.calibrate import Calibration, label, near_optimal, noise_margin
from pnp_twin.studies.calibrate_fields import raw_with_values
from pnp_twin.studies.summary import BOUNDS
from pnp_twin.twin.loader import apply_overrides, find_scenario, read_mapping
from pnp_twin.twin.output import dumps_toml, write_json, write_table, write_text

SCENARIO_FILE = "scenario.toml"
SUMMARY_FILE = "calibration.json"


def _num(v: Any) -> float | None:
    return None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)


def _bounded(kpi: str, x: float) -> float | None:
    """An interval's bound as shown: inside the KPI's own range (G in [0, 100] %)."""
    v = _num(x)
    lo, hi = BOUNDS.get(kpi, (-math.inf, math.inf))
    return None if v is None else min(max(v, lo), hi)


def points_rows(cal: Calibration) -> list[dict[str, Any]]:
    """One row per point and measured KPI."""
    t = cal.problem.targets
    rows = []
    for i, pred in enumerate(cal.best.predictions):
        for j, k in enumerate(t.kpis):
            if math.isnan(t.target[i, j]):
                continue
            row: dict[str, Any] = {"point": i + 1}
            row.update({r.path: v for r, v in t.point(i).items()})
            row.update(
                kpi=k,
                target=float(t.target[i, j]),
                predicted=pred.mean[k],
                ci_low=_bounded(k, pred.ci_low[k]),
                ci_high=_bounded(k, pred.ci_high[k]),
                residual=float(cal.best.residuals[i, j]),
                weight=float(t.weight[i]),
                policy=pred.policy,
            )
            rows.append(row)
    return rows


def profile_rows(cal: Calibration) -> list[dict[str, Any]]:
    """The one- and two-parameter profiles as rows."""
    names = [p.name for p in cal.problem.params]
    rows: list[dict[str, Any]] = []
    for j, line in enumerate(cal.profiles):
        rows += [
            {"param": names[j], "value": v, "param_2": "", "value_2": None, "objective": o}
            for v, o in line
        ]
    for j, m, grid in cal.pairs:
        rows += [
            {"param": names[j], "value": a, "param_2": names[m], "value_2": b, "objective": o}
            for a, b, o in grid
        ]
    return rows


def curve_rows(cal: Calibration) -> list[dict[str, Any]]:
    """The response curves as rows, one per field value and KPI."""
    rows = []
    for ref, line in cal.curves:
        for value, pred in line:
            for k in cal.problem.targets.kpis:
                rows.append(
                    {
                        "field": ref.path,
                        "value": value,
                        "kpi": k,
                        "predicted": pred.mean[k],
                        "ci_low": _bounded(k, pred.ci_low[k]),
                        "ci_high": _bounded(k, pred.ci_high[k]),
                        "policy": pred.policy,
                    }
                )
    return rows


def summary(cal: Calibration, command: str, scenario_file: Path) -> dict[str, Any]:
    """The calibration in one JSON-ready object (the ``--json`` output and the report's data)."""
    p = cal.problem
    start = p.start()
    params = []
    noise = noise_margin(p, cal.best)
    for j, prm in enumerate(p.params):
        lo, hi = (
            near_optimal(cal.profiles[j], cal.best.objective, noise["margin"])
            if cal.profiles[j]
            else (None, None)
        )
        params.append(
            {
                "name": prm.name,
                "low": prm.low,
                "high": prm.high,
                "start": float(start[j]),
                "value": cal.best.x[j],
                "near_optimal": [lo, hi],
            }
        )
    sc = p.scenario
    return {
        "fitted": cal.fitted,
        "params": params,
        "objective": cal.best.objective,
        "near_optimal_margin": noise["margin"],
        "noise": noise,
        "points": points_rows(cal),
        "kpis": list(p.targets.kpis),
        "varied": [r.path for r in p.targets.varied],
        "targets_file": p.targets.source,
        "policies": list(p.policies),
        "replications": p.replications,
        "duration": sc.duration,
        "warmup": sc.warmup,
        "seed": sc.seed,
        "scenario": sc.name,
        "evaluations": len(cal.history),
        "simulated_points": cal.simulated,
        "replayed_points": cal.replayed,
        "engine": cal.extra.get("engine", "auto"),
        "engines_ran": list(cal.extra.get("engines_ran", [])),
        "optimiser": f"scipy.optimize.minimize(method='Nelder-Mead', bounds): {cal.message}",
        "history": [{"x": list(x), "objective": o} for x, o in cal.history],
        "profiles": profile_rows(cal),
        "curves": curve_rows(cal),
        "wall_time": cal.wall_time,
        "command": command,
        "date": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "scenario_file": str(scenario_file),
        "lower_found": (
            {"x": list(cal.extra["lower"][0]), "objective": cal.extra["lower"][1]}
            if "lower" in cal.extra
            else None
        ),
    }


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def header(cal: Calibration, info: dict[str, Any]) -> str:
    """The comment block at the head of the calibrated scenario file."""
    p = cal.problem
    t = p.targets
    lines = [
        f"Calibrated by `pnp-twin calibrate` on {info['date']}:",
        *textwrap.wrap(
            info["command"],
            96,
            initial_indent="  ",
            subsequent_indent="    ",
            break_on_hyphens=False,
            break_long_words=False,
        ),
        *textwrap.wrap(
            f"Fitted to {t.source} ({t.n} points; {', '.join(t.kpis)}), the prediction at each "
            f"point being the best of {', '.join(p.policies)} over {p.replications} "
            f"common-random-number replications of {p.scenario.duration:g} s (warm-up "
            f"{p.scenario.warmup:g} s).",
            98,
        ),
        "Fitted (bounds; start -> fitted):",
    ]
    for q in info["params"]:
        lines.append(
            f"  {q['name']} [{q['low']:g}, {q['high']:g}]: {q['start']:.4g} -> {q['value']:.4g}"
        )
    lines.append("Residuals (measured -> predicted [95 % CI], predicted - measured):")
    for row in info["points"]:
        i = row["point"] - 1
        ci = ""
        if row["ci_low"] is not None:
            ci = f" [{row['ci_low']:.4g}, {row['ci_high']:.4g}]"
        lines.append(
            f"  point {label(t, i)}: {row['kpi']} {row['target']:.4g} -> "
            f"{row['predicted']:.4g}{ci} ({row['residual']:+.3g}, {row['policy']})"
        )
    lines += textwrap.wrap(
        f"Objective (weighted sum of squared residuals): {cal.best.objective:.4g} after "
        f"{info['evaluations']} evaluations. The input file's own comments are not carried over.",
        98,
    )
    return "".join(f"# {line}\n" for line in lines)


def scenario_mapping(cal: Calibration, source: str, sets: dict[str, Any]) -> dict[str, Any]:
    """The input file's mapping with ``--set`` and the fitted values applied."""
    path = find_scenario(source)
    data = apply_overrides(read_mapping(path), sets) if sets else read_mapping(path)
    data = raw_with_values(data, cal.problem.values(cal.best.x), cal.problem.scenario)
    trace = data.get("feeder", {}).get("trace") if isinstance(data.get("feeder"), dict) else None
    if isinstance(trace, str) and not Path(trace).is_absolute():  # the file moves elsewhere
        data["feeder"]["trace"] = str((path.parent / trace).resolve())
    elif isinstance(trace, list):  # several traces: each made absolute
        data["feeder"]["trace"] = [str((path.parent / str(t)).resolve()) for t in trace]
    return data


def write_outputs(
    cal: Calibration, folder: Path, source: str, sets: dict[str, Any], command: str
) -> dict[str, Any]:
    """Write every output (module docstring) into ``folder``; returns the summary."""
    folder = Path(folder)
    scenario_file = folder / SCENARIO_FILE
    info = summary(cal, command, scenario_file)
    body = dumps_toml(scenario_mapping(cal, source, sets))
    write_text(header(cal, info) + body, scenario_file)
    write_table(pd.DataFrame(info["points"]), folder / "points.csv")
    write_table(
        pd.DataFrame(
            info["profiles"], columns=["param", "value", "param_2", "value_2", "objective"]
        ),
        folder / "profile.csv",
    )
    write_table(pd.DataFrame(info["curves"]), folder / "curve.csv")
    write_json(info, folder / SUMMARY_FILE)
    return info


def max_abs_residual(info: dict[str, Any], kpi: str = "gripping_rate") -> float:
    """The largest |residual| of one KPI over the points (NaN if it was not measured)."""
    res = [abs(r["residual"]) for r in info["points"] if r["kpi"] == kpi]
    return float(np.max(res)) if res else math.nan
