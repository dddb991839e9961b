"""KPIs straight from the fast engine's arrays, without building the record tables.

:func:`array_kpis` is :func:`twin.kpis.compute_kpis` applied to what
:meth:`twin.records.Recorder.parts_frame` and ``spans_frame`` would build, operation for
operation on the same numpy arrays in the same order, so every float is the same. It is a
mirror, so it is used only while ``twin/kpis.py`` and ``twin/records.py`` are the files it
was checked against (:data:`MIRRORS`, their SHA-256); after any change to them the fast
engine computes KPIs from the tables (slower, still identical) until the mirror is checked
again (``tests/twin/test_engine_identity.py`` says so).
"""

from __future__ import annotations

import hashlib
import math
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from twin.fast import layout as L
from twin.kpis import STATES, WELCH_BINS, clipped, robot_capacity

if TYPE_CHECKING:
    from twin.fast.engine import FastLine

MIRRORS = {
    "kpis.py": "8e3713bf5bb5cdc338c443feeff5a94663928ad7137989d96d673979c89e3ca4",
    "records.py": "05e97fe8837b10fdf86d0def18f1e41c18573fdbd30bdaee05791dbaff5891e2",
}
"""SHA-256 of the twin's files this module mirrors, as last checked."""


def source_digests() -> dict[str, str]:
    """SHA-256 of the mirrored files as they are now."""
    root = Path(__file__).resolve().parents[1]
    return {name: hashlib.sha256((root / name).read_bytes()).hexdigest() for name in MIRRORS}


@cache
def mirror_is_current() -> bool:
    """True when the mirrored files are unchanged since the mirror was checked."""
    try:
        return source_digests() == MIRRORS
    except OSError:
        return False


def _welch(fed: np.ndarray, is_picked: np.ndarray, duration: float) -> list[float]:
    bins = WELCH_BINS
    inside = (fed >= 0) & (fed < duration)
    k = np.minimum((fed[inside] / duration * bins).astype(np.int64), bins - 1)
    picked = is_picked[inside]
    n = np.bincount(k, minlength=bins)
    hit = np.bincount(k, weights=picked.astype(float), minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(n > 0, 100.0 * hit / np.maximum(n, 1), np.nan)
    return [round(float(x), 3) for x in g]


def _state_times(line: FastLine, is_picked: np.ndarray, w0: float, w1: float) -> np.ndarray:
    n = len(line.specs)
    out = np.zeros((n, len(STATES)))
    if is_picked.any():
        busy = clipped(line.rec_f[is_picked, 0], line.rec_f[is_picked, 2], w0, w1)
        np.add.at(out[:, 0], line.rec_i[is_picked, 0], busy)
    k = int(line.gs[L.NSPANS])
    if k:
        lengths = clipped(line.sp_f[:k, 0], line.sp_f[:k, 1], w0, w1)
        rob = line.sp_i[:k, 0]
        state = line.sp_i[:k, 1]
        for j, name in enumerate(STATES):
            code = L.SPAN_NAMES.index("interrupted" if name == "busy" else name)
            mask = state == code
            np.add.at(out[:, j], rob[mask], lengths[mask])
        out[:, 0] -= out[:, STATES.index("blocked")]
    return out


def array_kpis(line: FastLine, warmup: float, duration: float) -> dict[str, Any]:
    """compute_kpis(parts_frame, spans_frame, ...) of a finished FastLine, from its arrays."""
    specs = line.specs
    n = len(specs)
    w0, w1 = warmup, duration
    span = w1 - w0
    fed = line.fed
    picked_at = line.rec_f[:, 1]
    is_picked_all = ~np.isnan(picked_at)
    win = (fed >= w0) & (fed < w1)
    presented = int(win.sum())
    is_picked = is_picked_all[win]
    picked = int(is_picked.sum())
    robot_all = np.where(is_picked_all, line.rec_i[:, 0].astype(float), np.nan)
    robot_of = robot_all[win]
    picks = np.bincount(robot_of[is_picked].astype(np.int64), minlength=n)[:n]
    states = _state_times(line, is_picked_all, w0, w1)
    nominal = np.array([robot_capacity(s) for s in specs])
    decided = np.where(is_picked_all, line.rec_f[:, 0], np.nan)[win]
    cycle_all = line.rec_f[win, 2] - decided
    busy = states[:, 0]
    worked = (busy > 0) & (picks > 0)
    caps = np.where(worked, picks / np.where(worked, busy, 1.0), nominal)
    flow = presented / span
    max_tp = min(flow, float(caps.sum()))
    tp = picked / span
    cycles = cycle_all[is_picked]
    lost = int(np.sum(~is_picked))
    robots = []
    for i in range(n):
        mine = cycle_all[is_picked & (robot_of == i)]
        robots.append(
            {
                "robot": i + 1,
                "workspace": list(specs[i].workspace),
                "picks": int(picks[i]),
                "throughput": float(picks[i] / span),
                "utilisation": float(states[i, 0] / span),
                "noop": float(states[i, 1] / span),
                "wait": float(states[i, 2] / span),
                "blocked": float(states[i, 3] / span),
                "down": float(states[i, 4] / span),
                "availability": float(1.0 - states[i, 4] / span),
                "passed_on": int(np.sum(robot_of[is_picked] > i)),
                "lost": lost,
                "cycle_time_mean": float(mine.mean()) if len(mine) else math.nan,
                "capacity": float(caps[i]),
                "nominal_capacity": float(nominal[i]),
            }
        )
    k = int(line.gs[L.NSPANS])
    starts = line.sp_f[:k, 0]
    noops = (line.sp_i[:k, 1] == L.S_NOOP) & (starts >= w0) & (starts < w1)
    codes = line.rec_i[win, 1][is_picked]
    found = np.bincount(codes, minlength=L.NOOP)
    rules: dict[str, int] = {L.RULE_NAMES[c]: int(found[c]) for c in np.flatnonzero(found)}
    rules["NooP"] = int(noops.sum())
    return {
        "gripping_rate": 100.0 * picked / presented if presented else math.nan,
        "parts_presented": presented,
        "parts_picked": picked,
        "parts_missed": presented - picked,
        "throughput": tp,
        "part_flow": flow,
        "max_throughput": max_tp,
        "efficiency": tp / max_tp if max_tp > 0 else math.nan,
        "utilisation": float(states[:, 0].sum() / (span * n)),
        "cycle_time_mean": float(cycles.mean()) if len(cycles) else math.nan,
        "cycle_time_p50": float(np.percentile(cycles, 50)) if len(cycles) else math.nan,
        "cycle_time_p95": float(np.percentile(cycles, 95)) if len(cycles) else math.nan,
        "cycle_time_max": float(cycles.max()) if len(cycles) else math.nan,
        "decisions": {str(k): int(v) for k, v in sorted(rules.items())},
        "window": [w0, w1],
        "welch_gripping_rate": _welch(fed, is_picked_all, w1),
        "robots": robots,
    }
