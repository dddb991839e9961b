"""Trace replay files (twin.trace): every mistake names the file and line; epoch times are
offset to the first arrival; a run longer than its trace is refused."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.twin import simulate
from pnp_twin.twin.feeder import read_trace as feeder_read_trace
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.trace import EPOCH, TraceError, check_replay, load_trace, read_trace

WIDTH = 0.4


def write(tmp_path: Path, text: str | bytes, name: str = "t.csv") -> Path:
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


BAD: dict[str, tuple[str | bytes, list[str]]] = {
    "empty file": ("", ["is empty", "header"]),
    "header only": ("time,y\n", ["header but no rows"]),
    "no header": ("0.5,0.1\n0.7,0.2\n", ["line 1", "header", "time, y"]),
    "missing y": ("time,kind\n0.5,A\n", ["line 1", "lacks column y"]),
    "unknown column": ("time,y,speed\n0.5,0.1,3\n", ["line 1", "unknown column 'speed'"]),
    "column twice": ("time,y,y\n0.5,0.1,0.2\n", ["line 1", "twice"]),
    "short row": ("time,y\n0.1,0.2\n0.3\n", ["line 3", "1 values", "2 columns"]),
    "non-numeric time": ("time,y\n0.1,0.2\nsoon,0.1\n", ["line 3", "time 'soon'", "non-numeric"]),
    "non-numeric y": ("time,y\n0.1,middle\n", ["line 2", "y 'middle'"]),
    "nan time": ("time,y\n0.1,0.2\nnan,0.1\n", ["line 3", "time nan", "not a finite"]),
    "inf y": ("time,y\n0.1,inf\n", ["line 2", "y inf", "not a finite"]),
    "negative time": ("time,y\n-1,0.2\n", ["line 2", "negative"]),
    "out of order": (
        "time,y\n2,0.2\n1,0.1\n",
        ["line 3", "before the row above", "non-decreasing"],
    ),
    "off the belt": ("time,y\n0.5,0.9\n", ["line 2", "y 0.9", "outside the belt", "0..0.4"]),
    "below the belt": ("time,y\n0.5,0.1\n0.6,-0.01\n", ["line 3", "outside the belt"]),
    "long kind": ("time,y,kind\n0.5,0.1," + "k" * 100 + "\n", ["line 2", "kind", "64"]),
    "not UTF-8": (b"time,y\n0.5,0.1\n\xff\xfe,0.2\n", ["not UTF-8", "line 3"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_each_bad_trace_is_one_line_naming_file_and_line(tmp_path: Path, case: str) -> None:
    text, needles = BAD[case]
    path = write(tmp_path, text)
    with pytest.raises(TraceError) as info:
        load_trace(path, WIDTH)
    message = str(info.value)
    assert "\n" not in message and len(message) < 300
    assert message.startswith("feeder.trace: ") and str(path) in message
    for needle in needles:
        assert needle in message, f"{needle!r} not in {message!r}"


def test_a_good_trace_reads_with_kinds_a_bom_and_blank_lines(tmp_path: Path) -> None:
    path = write(tmp_path, "\ufefftime,y,kind\n0.1,0.2,A\n\n0.1,0.3,\n0.4,0.0,B\n")
    trace = load_trace(path, WIDTH)
    assert trace.times.tolist() == [0.1, 0.1, 0.4]
    assert trace.ys.tolist() == [0.2, 0.3, 0.0]
    assert trace.kinds == ["A", "", "B"]
    assert trace.offset == 0.0
    times, ys, kinds = read_trace(path, WIDTH)
    assert feeder_read_trace is read_trace  # the old import path still works
    assert times.tolist() == trace.times.tolist() and kinds == trace.kinds


def test_epoch_times_are_offset_to_the_first_arrival(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    t0 = 1_733_000_000.25  # 2024, as Unix time
    path = write(tmp_path, f"time,y\n{t0},0.1\n{t0 + 0.5},0.2\n{t0 + 2},0.3\n")
    with caplog.at_level(logging.INFO, logger="pnp_twin.twin.trace"):
        trace = load_trace(path, WIDTH)
    assert trace.offset == t0
    assert np.allclose(trace.times, [0.0, 0.5, 2.0])
    assert "wall-clock" in caplog.text
    assert t0 >= EPOCH


def test_small_times_are_not_offset(tmp_path: Path) -> None:
    trace = load_trace(write(tmp_path, "time,y\n5.0,0.1\n6.0,0.2\n"), WIDTH)
    assert trace.offset == 0.0 and trace.times.tolist() == [5.0, 6.0]


def scenario_file(tmp_path: Path, trace: str, duration: float, warmup: float = 1.0) -> Path:
    path = tmp_path / "line.yaml"
    path.write_text(
        f"feeder: {{arrival: trace, trace: t.csv}}\nduration: {duration}\nwarmup: {warmup}\n",
        encoding="utf-8",
    )
    write(tmp_path, trace)
    return path


def rows(n: int, gap: float, start: float = 0.0) -> str:
    return "time,y\n" + "".join(f"{start + i * gap:.3f},0.2\n" for i in range(n))


def test_a_duration_past_the_trace_end_is_refused_with_its_span(tmp_path: Path) -> None:
    path = scenario_file(tmp_path, rows(50, 0.2), duration=600)
    with pytest.raises(TraceError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith("duration: 600 s runs past the end of the trace")
    assert "50 parts from 0 to 9.8 s" in message
    assert "--set duration=10.8" in message


def test_a_duration_within_the_trace_loads_and_replays_every_part(tmp_path: Path) -> None:
    path = scenario_file(tmp_path, rows(50, 0.2), duration=10.0)
    scenario = load_scenario(path)
    trace = check_replay(scenario)
    assert trace is not None and len(trace.times) == 50
    result = simulate(scenario, make_policy("SD"))
    assert len(result.parts) == 50
    assert result.kpis["parts_presented"] == int((trace.times >= 1.0).sum())


def test_an_epoch_trace_replays_from_zero(tmp_path: Path) -> None:
    path = scenario_file(tmp_path, rows(50, 0.2, start=1.7e9), duration=10.0)
    result = simulate(load_scenario(path), make_policy("SD"))
    assert len(result.parts) == 50
    assert result.parts["fed_at"].iloc[0] == 0.0
    assert result.kpis["parts_presented"] > 0


def test_a_window_without_parts_is_refused(tmp_path: Path) -> None:
    path = scenario_file(tmp_path, rows(5, 0.1), duration=1.3, warmup=1.0)
    with pytest.raises(TraceError, match=r"warmup: no part of the trace .* \[1, 1.3\) s"):
        load_scenario(path)


def test_the_shipped_trace_scenario_is_within_its_trace() -> None:
    scenario = load_scenario("trace_replay")
    trace = check_replay(scenario)
    assert trace is not None and scenario.duration <= trace.end
