"""Recorded arrival traces: the CSV a ``trace`` feeder replays, read and checked row by row.

A trace is UTF-8 CSV (a leading BOM is fine) with a header naming the columns ``time``
(s from the start of the recording), ``y`` (m across the belt, 0 = lower edge) and,
optionally, ``kind`` (free text, at most 64 characters); no other column. Every row holds
finite numbers, times are >= 0 and non-decreasing, every y lies on the belt. Each mistake
is one :class:`TraceError` line naming the file, the line and the value.

Wall-clock times: when the first time is at least :data:`EPOCH` s (a Unix time after March
1973, far longer than any recording), the times are taken as wall-clock (epoch) seconds and
offset so that the first part arrives at t = 0; the offset is logged (INFO) and kept in
:attr:`Trace.offset`.

Duration: :func:`check_replay` refuses a run whose ``duration`` goes past the trace's end
(its last arrival plus one mean gap), since the feed would stop and dilute every rate, and
a run whose measurement window holds no part of the trace. The message gives the span and
the duration to use (``--set duration=...``).
"""

from __future__ import annotations

import csv
import io
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.twin.errors import ScenarioError, clip, tail
from pnp_twin.twin.inputs import TRACE_BYTES, folder_files, read_user_text
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

EPOCH = 1e8  # s: a first time this late is a wall-clock (epoch) stamp, not a run time
MAX_KIND = 64
COLUMNS = ("time", "y", "kind")


class TraceError(ScenarioError):
    """A trace file that cannot be replayed; the message is one line."""


@dataclass(frozen=True)
class Trace:
    """A trace as replayed: arrival times (offset applied), lateral positions, kinds."""

    path: Path
    times: np.ndarray
    ys: np.ndarray
    kinds: list[str] | None
    offset: float = 0.0
    lines: tuple[int, ...] = ()  # the file's line number of each row

    @property
    def end(self) -> float:
        """When the recording ends: the last arrival plus one mean gap (at least 1 s)."""
        n, first, last = len(self.times), float(self.times[0]), float(self.times[-1])
        gap = (last - first) / (n - 1) if n > 1 else 0.0
        return last + max(gap, 1.0)


def trace_file(scenario: Scenario) -> Path | None:
    """The (first) trace a scenario replays, resolved against its file's folder; None if none."""
    files = trace_files(scenario)
    return files[0] if files else None


def trace_files(scenario: Scenario) -> list[Path]:
    """Every trace a scenario replays (one, a list, or a folder's CSV files by name)."""
    if scenario.feeder.arrival != "trace" or not scenario.feeder.trace:
        return []
    return trace_paths(scenario.feeder.trace, scenario.source_dir)


def trace_folders(scenario: Scenario) -> list[Path]:
    """The folders ``feeder.trace`` names (each holds traces), resolved as its files are."""
    if scenario.feeder.arrival != "trace" or not scenario.feeder.trace:
        return []
    trace = scenario.feeder.trace
    names = [trace] if isinstance(trace, str) else list(trace)
    paths = (resolve(str(name), scenario.source_dir) for name in names)
    return [p for p in paths if p.is_dir()]


def trace_paths(trace: str | Sequence[str], source_dir: str | Path | None) -> list[Path]:
    """The files ``feeder.trace`` names: a file, a list of files, or a folder whose ``*.csv``
    files (sorted by name) are the traces; a folder without one is refused naming it, and so
    is a trace named twice (directly, through a link or a folder): it would count twice."""
    out: list[Path] = []
    for name in [trace] if isinstance(trace, str) else list(trace):
        path = resolve(str(name), source_dir)
        if path.is_dir():
            found = folder_files(path, "feeder.trace", ".csv", TraceError)
            if not found:
                raise TraceError(
                    f"feeder.trace: '{path}' is a folder without .csv traces; give a trace "
                    "file, a list of them, or a folder of time,y[,kind] CSV files"
                )
            out += found
        else:
            out.append(path)
    _check_distinct(out)
    return out


def _check_distinct(paths: Sequence[Path]) -> None:
    """Refuse a trace named twice: the replications would not be independent samples."""
    seen: dict[object, Path] = {}
    for path in paths:
        try:
            st = path.stat()
            key: object = (st.st_dev, st.st_ino)  # a hard link is the same trace too
        except OSError:
            key = path.resolve()
        if key in seen:
            raise TraceError(
                f"feeder.trace: '{tail(str(path))}' is named twice (also as "
                f"'{tail(str(seen[key]))}'); each trace is one replication, so list it once"
            )
        seen[key] = path


def for_replication(scenario: Scenario, replication: int) -> Scenario:
    """``scenario`` as replication ``replication`` of a study runs it: with several traces,
    replaying the replication's own trace (replication k replays trace k); else unchanged."""
    files = trace_files(scenario)
    if len(files) <= 1:
        return scenario
    if not 0 <= replication < len(files):
        raise TraceError(
            f"feeder.trace: replication {replication + 1} has no trace; the {len(files)} "
            f"traces are the replications, so give at most {len(files)} replications"
        )
    feeder = scenario.feeder.model_copy(update={"trace": str(files[replication])})
    return scenario.model_copy(update={"feeder": feeder})


def check_replications(scenario: Scenario, n: int, option: str = "replications") -> None:
    """Refuse ``n`` replications (or seeds) of a scenario replaying fewer than ``n`` traces
    of a list or folder: replication k replays trace k everywhere, so a trace never counts
    twice and the same replication never replays another trace (checked before any run)."""
    files = trace_files(scenario)
    if len(files) > 1 and n > len(files):
        raise TraceError(
            f"{option}: {n} asked, but feeder.trace holds {len(files)} traces and replication "
            f"k replays trace k; give at most {len(files)}, or more traces"
        )


def resolve(trace: str, source_dir: str | Path | None) -> Path:
    """A trace path as a scenario file names it: relative ones from the file's folder."""
    path = Path(trace)
    if not path.is_absolute() and source_dir:
        path = Path(source_dir) / path
    return path


def _header(path: Path, header: list[str] | None) -> list[str]:
    where = f"feeder.trace: '{path}'"
    if header is None:
        raise TraceError(f"{where} is empty; give a header line time,y[,kind] and one row per part")
    names = [h.strip() for h in header]
    unknown = [h for h in names if h not in COLUMNS]
    missing = [c for c in ("time", "y") if c not in names]
    if missing or unknown:
        bad = f"lacks column {missing[0]}" if missing else f"has unknown column '{unknown[0]}'"
        raise TraceError(
            f"{where} line 1: the header {clip(','.join(names), 40)!r} {bad}; it needs a "
            "header with columns time, y[, kind]"
        )
    if len(set(names)) != len(names):
        twice = next(n for i, n in enumerate(names) if n in names[:i])
        raise TraceError(
            f"{where} line 1: the header names column '{twice}' twice; give each column once"
        )
    return names


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise TraceError(
            f"feeder.trace: '{path}' line {line}: {column} {clip(text, 30)!r} is non-numeric; "
            f"give {column} as a number"
        ) from None
    if not math.isfinite(value):
        raise TraceError(
            f"feeder.trace: '{path}' line {line}: {column} {text.strip()} is not a finite number"
        )
    return value


def _rows(path: Path, text: str) -> tuple[list[float], list[float], list[str] | None, list[int]]:
    reader = csv.reader(io.StringIO(text, newline=""))
    names = _header(path, next(reader, None))
    at = {name: i for i, name in enumerate(names)}
    times: list[float] = []
    ys: list[float] = []
    kinds: list[str] | None = [] if "kind" in at else None
    lines: list[int] = []
    for row in reader:
        line = reader.line_num
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(names):
            raise TraceError(
                f"feeder.trace: '{path}' line {line}: {len(row)} values for the header's "
                f"{len(names)} columns ({','.join(names)})"
            )
        lines.append(line)
        times.append(_number(path, line, "time", row[at["time"]]))
        ys.append(_number(path, line, "y", row[at["y"]]))
        if kinds is not None:
            kind = row[at["kind"]].strip()
            if len(kind) > MAX_KIND:
                raise TraceError(
                    f"feeder.trace: '{path}' line {line}: kind is {len(kind)} characters; "
                    f"at most {MAX_KIND} allowed"
                )
            kinds.append(kind)
    if not times:
        raise TraceError(
            f"feeder.trace: '{path}' has a header but no rows; give one row time,y[,kind] per part"
        )
    return times, ys, kinds, lines


def load_trace(path: Path, width: float) -> Trace:
    """Read and check a trace for a belt ``width`` m wide (see the module docstring)."""
    text = read_user_text(path, "feeder.trace", TRACE_BYTES, TraceError)
    t_list, y_list, kinds, lines = _rows(path, text)
    times, ys = np.array(t_list), np.array(y_list)
    neg = np.flatnonzero(times < 0)
    if len(neg):
        i = int(neg[0])
        raise TraceError(
            f"feeder.trace: '{path}' line {lines[i]}: time {times[i]:g} is negative; times "
            "are seconds from the start of the recording, >= 0"
        )
    back = np.flatnonzero(np.diff(times) < 0)
    if len(back):
        i = int(back[0]) + 1
        raise TraceError(
            f"feeder.trace: '{path}' line {lines[i]}: time {times[i]:g} is before the row "
            f"above ({times[i - 1]:g}); times must be non-decreasing"
        )
    off = np.flatnonzero((ys < 0) | (ys > width))
    if len(off):
        i = int(off[0])
        raise TraceError(
            f"feeder.trace: '{path}' line {lines[i]}: y {ys[i]:g} is outside the belt "
            f"(0..{width:g} m, belt.width)"
        )
    offset = 0.0
    if times[0] >= EPOCH:
        offset = float(times[0])
        times = times - offset
        log.info(
            "trace %s: times from %.0f s look like wall-clock (epoch) seconds; offset so the "
            "first part arrives at t = 0",
            path,
            offset,
        )
    return Trace(path, times, ys, kinds, offset, tuple(lines))


def read_trace(path: Path, width: float) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """(times, y, kinds or None) of a trace CSV with columns time, y[, kind]."""
    trace = load_trace(path, width)
    return trace.times, trace.ys, trace.kinds


def check_replay(scenario: Scenario) -> Trace | None:
    """The (first) trace ``scenario`` replays; every one is checked (:func:`check_replays`)."""
    traces = check_replays(scenario)
    return traces[0] if traces else None


def check_replays(scenario: Scenario) -> list[Trace]:
    """Every trace ``scenario`` replays, each checked against its duration and warm-up."""
    return [_checked(scenario, path) for path in trace_files(scenario)]


def _checked(scenario: Scenario, path: Path) -> Trace:
    trace = load_trace(path, scenario.belt.width)
    first, last, end = float(trace.times[0]), float(trace.times[-1]), trace.end
    span = f"{len(trace.times)} parts from {first:g} to {last:g} s"
    if scenario.duration > end + 1e-9:
        raise TraceError(
            f"duration: {scenario.duration:g} s runs past the end of the trace '{path}' "
            f"({span}), so the feed would stop early; give duration <= {end:.6g} "
            f"(--set duration={math.floor(end * 1000) / 1000:g})"
        )
    _check_kinds(scenario, trace)
    counted = int(((trace.times >= scenario.warmup) & (trace.times < scenario.duration)).sum())
    if counted == 0:
        raise TraceError(
            f"warmup: no part of the trace '{path}' ({span}) is fed in the measurement window "
            f"[{scenario.warmup:g}, {scenario.duration:g}) s; lower warmup or raise duration"
        )
    return trace


def _check_kinds(scenario: Scenario, trace: Trace) -> None:
    """On a line with feeder.kinds, every row's kind must name one of them."""
    names = [k.name for k in scenario.feeder.kinds]
    if not names:
        return
    if trace.kinds is None:
        raise TraceError(
            f"feeder.trace: '{trace.path}' has no kind column, but feeder.kinds names "
            f"{', '.join(names)}; add a kind column (time,y,kind) or remove feeder.kinds"
        )
    known = set(names)
    for i, kind in enumerate(trace.kinds):
        if kind not in known:
            raise TraceError(
                f"feeder.trace: '{trace.path}' line {trace.lines[i]}: kind '{kind}' is not "
                f"a kind of feeder.kinds; allowed {', '.join(names)}"
            )


def gap_stats(trace: Trace | Sequence[Trace]) -> tuple[float, float]:
    """(mean rate in parts/s, coefficient of variation of the gaps) of a trace (or of several,
    their gaps pooled): the rate is the parts after the first over the span they arrive in."""
    traces = [trace] if isinstance(trace, Trace) else list(trace)
    gaps = np.concatenate([np.diff(t.times) for t in traces]) if traces else np.empty(0)
    if len(gaps) == 0 or float(gaps.sum()) <= 0:
        return math.nan, math.nan
    mean = float(gaps.mean())
    cv = float(gaps.std(ddof=1)) / mean if len(gaps) > 1 else 0.0
    return 1.0 / mean, cv


def arrival_from_trace(
    data: dict[str, Any], overrides: Mapping[str, Any], source_dir: str | Path | None
) -> tuple[dict[str, Any], str | None]:
    """``--set feeder.arrival=poisson`` (or normal, fixed) on a scenario that replays a
    trace: the trace is dropped and its mean rate (and, for normal gaps, its coefficient of
    variation) become ``feeder.rate`` (and ``feeder.cv``) unless those are set too. Returns
    the raw scenario data to override and the line saying so (None when nothing changed)."""
    feeder = data.get("feeder")
    arrival = overrides.get("feeder.arrival")
    if (
        not isinstance(feeder, dict)
        or feeder.get("arrival") != "trace"
        or not feeder.get("trace")
        or arrival in (None, "trace")
        or "feeder.trace" in overrides
    ):
        return data, None
    raw = feeder["trace"]
    paths = trace_paths(raw if isinstance(raw, str) else [str(p) for p in raw], source_dir)
    width = (data.get("belt") or {}).get("width")
    belt = float(width) if isinstance(width, int | float) else math.inf
    traces = [load_trace(p, belt) for p in paths]
    rate, cv = gap_stats(traces)
    parts = sum(len(t.times) for t in traces)
    path = paths[0]
    named = f"the trace '{path.name}'" if len(paths) == 1 else f"the {len(paths)} traces"
    named += f" ({parts} parts)"
    out = {**data, "feeder": {k: v for k, v in feeder.items() if k != "trace"}}
    said = []
    if "feeder.rate" not in overrides and math.isfinite(rate):
        out["feeder"]["rate"] = round(rate, 6)
        said.append(f"its mean rate {rate:.4g} parts/s")
    if arrival == "normal" and "feeder.cv" not in overrides and math.isfinite(cv):
        out["feeder"]["cv"] = round(min(cv, 10.0), 6)
        said.append(f"its gaps' coefficient of variation {cv:.3g}")
    what = " and ".join(said) or "the rate and CV you set"
    said_line = f"feeder.arrival = {arrival}: replaces {named} with {arrival} arrivals at {what}"
    return out, said_line
