"""The bad-input suite: a hostile or careless user, across every command and file kind.

Each case writes its files into an empty folder (beside a sentinel output that must survive),
runs one command and asserts what every user mistake must give: exit code 2, nothing on
stdout, exactly one short ``error:`` line on stderr that names the file / field / row (the
case's needles), no traceback, an answer within a few seconds, and every file that existed
before unchanged with no new file written.

Most cases run in-process (typer's CliRunner, under an alarm so a hang fails instead of
blocking the suite); :data:`SUBPROCESS` runs a sample again as ``python -m pnp_twin``, where
a traceback or a slow start could not hide.
"""

from __future__ import annotations

import hashlib
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app

SECONDS = 10.0  # "within a few seconds", with room for a loaded machine
PROCESS_SECONDS = 45.0  # the same, plus starting Python and importing the stack
MAX_LINE = 400  # characters: one line, room to list what is allowed


@dataclass(frozen=True)
class Case:
    """One bad input: the files to write, the command line, what the line must name."""

    args: list[str]
    needles: list[str]
    files: dict[str, str | bytes] = field(default_factory=dict)


TRACE = "time,y\n0.1,0.2\n0.5,0.1\n0.9,0.3\n"
TRACE_LINE = "feeder: {arrival: trace, trace: t.csv}\nduration: 1.0\nwarmup: 0.0\n"
LAUGHS = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)}]\n"
    for i in range(9)
)
RATES = [float(i) for i in range(1, 1001)]
SPEEDS = [round(0.5 + i / 10_000, 4) for i in range(1000)]
BIG_GRID = f"sweep.grid={{'feeder.rate': {RATES}, 'belt.speed': {SPEEDS}}}"
SHORT = ["--set", "sweep.duration=20", "--set", "sweep.warmup=2"]


def trace_case(text: str | bytes, needles: list[str], command: str = "run") -> Case:
    return Case(
        [command, "line.yaml"],
        ["feeder.trace", "t.csv", *needles],
        {"line.yaml": TRACE_LINE, "t.csv": text},
    )


def toml(text: str | bytes, needles: list[str], command: str = "run") -> Case:
    return Case([command, "s.toml"], needles, {"s.toml": text})


def sets(setting: str, needles: list[str], command: str = "run", name: str = "two_robot") -> Case:
    return Case([command, name, "--set", setting], needles)


CASES: dict[str, Case] = {
    # --- scenario files: finding, reading, parsing ------------------------------------------
    "missing file": Case(["run", "nothere.toml"], ["nothere.toml", "shipped name"]),
    "unknown shipped name": Case(["validate", "papr_baseline"], ["papr_baseline"]),
    "compare: one policy": Case(["compare", "two_robot", "-p", "SD"], ["--policy", "exactly two"]),
    "compare: report not html": Case(
        ["compare", "two_robot", "-p", "SD", "-p", "FIFO", "--report", "r.txt"],
        ["--report", "r.txt", ".html"],
    ),
    "run: gif not .gif": Case(["run", "two_robot", "--gif", "x.png"], ["--gif", "x.png", ".gif"]),
    "wrong suffix": Case(["run", "s.json"], ["s.json", ".toml, .yaml"], {"s.json": "{}"}),
    "a folder, not a file": Case(["run", "lines"], ["lines"], {"lines/keep": ""}),
    "bad TOML": toml("[belt\nspeed = 1\n", ["s.toml", "not valid TOML"]),
    "bad YAML": Case(["run", "b.yaml"], ["b.yaml", "not valid YAML"], {"b.yaml": "belt: [1, 2\n"}),
    "YAML list": Case(["validate", "l.yaml"], ["l.yaml", "mapping"], {"l.yaml": "- 1\n- 2\n"}),
    "empty TOML": toml("", ["s.toml", "is empty"]),
    "comments-only YAML": Case(["run", "c.yaml"], ["c.yaml", "is empty"], {"c.yaml": "# x\n"}),
    "non-UTF-8 TOML": toml('name = "caf\xe9"\n'.encode("latin-1"), ["s.toml", "not UTF-8"]),
    "non-UTF-8 YAML": Case(
        ["validate", "l.yaml"],
        ["l.yaml", "not UTF-8", "line 2"],
        {"l.yaml": b"name: x\ndescription: \xff\xfe\n"},
    ),
    "billion laughs": Case(["run", "lol.yaml"], ["lol.yaml", "aliases"], {"lol.yaml": LAUGHS}),
    "a huge file": Case(
        ["run", "big.yaml"],
        ["big.yaml", "at most 1,000,000"],
        {"big.yaml": "# " + "x" * 1_100_000 + "\n"},
    ),
    "deeply nested YAML": Case(
        ["run", "d.yaml"], ["d.yaml", "nested too deeply"], {"d.yaml": "[" * 5000 + "]" * 5000}
    ),
    # --- scenario fields: types, finiteness, bounds ------------------------------------------
    "unknown key": toml("[belt]\nspede = 1\n", ["belt.spede", "unknown key"]),
    "unknown section": toml("[belts]\nspeed = 1\n", ["belts", "unknown key"]),
    "count = true": toml("[robots]\ncount = true\n", ["robots.count", "True", "integer"]),
    "count as text": toml('[robots]\ncount = "four"\n', ["robots.count", "four", "integer"]),
    "count fractional": toml("[robots]\ncount = 2.5\n", ["robots.count", "2.5", "integer"]),
    "rate as text": toml('[feeder]\nrate = "10"\n', ["feeder.rate", "'10'", "number"]),
    "speed as bool": toml("[belt]\nspeed = false\n", ["belt.speed", "False", "number"]),
    "NaN bin offset": toml(
        "[robots]\nbin_offset = [nan, inf]\n", ["robots.bin_offset", "nan", "finite"]
    ),
    "infinite length": toml("[belt]\nlength = inf\n", ["belt.length", "inf", "finite"]),
    "YAML .nan": Case(
        ["run", "n.yaml"], ["belt.speed", "finite"], {"n.yaml": "belt:\n  speed: .nan\n"}
    ),
    "YAML yes as a count": Case(
        ["run", "y.yaml"], ["robots.count", "True"], {"y.yaml": "robots:\n  count: yes\n"}
    ),
    "pick_time 1e300": toml("[robots]\npick_time = 1e300\n", ["robots.pick_time", "60 s"]),
    "arm 1e9 m/s": toml("[robots]\narm_speed = 1e9\n", ["robots.arm_speed", "100 m/s"]),
    "acceleration 1e-9": toml(
        "[robots]\nacceleration = 1e-9\n", ["robots.acceleration", "too low", "0 for no limit"]
    ),
    "negative belt speed": toml("[belt]\nspeed = -1\n", ["belt.speed", "-1", "greater than 0"]),
    "duration 1e9": toml("duration = 1e9\n", ["duration", "31536000 s"]),
    "duration 0": toml("duration = 0\n", ["duration", "greater than 0"]),
    "seed too large": toml("seed = 99999999999999999999\n", ["seed"]),
    "grid of zero cells": toml("[belt]\ngrid = [0, 8]\n", ["belt.grid", "greater than or"]),
    "unknown termination": toml('termination = "t_some"\n', ["termination", "t_continue"]),
    "unknown arrival": toml('[feeder]\narrival = "burst"\n', ["feeder.arrival", "poisson"]),
    "name with a newline": toml('name = "a\\nb"\n', ["name"]),
    "section given as a number": Case(["run", "r.yaml"], ["robots"], {"r.yaml": "robots: 4\n"}),
    "source_dir in the file": toml('source_dir = "/etc"\n', ["source_dir", "not a scenario"]),
    # --- scenario fields: settings that contradict each other --------------------------------
    "trace with poisson": toml('[feeder]\ntrace = "t.csv"\n', ["feeder.trace", "arrival"]),
    "lateral spread 5 m": toml(
        "[feeder]\nlateral_sd = 5.0\n", ["feeder.lateral_sd", "wider than the belt"]
    ),
    "mean with uniform": toml(
        '[feeder]\nlateral = "uniform"\nlateral_mean = 0.1\n', ["feeder.lateral_mean", "uniform"]
    ),
    "arm slower than belt": toml("[robots]\narm_speed = 0.5\n", ["robots.arm_speed", "belt"]),
    "workspaces past the belt": toml(
        "[robots]\nworkspace_length = 1.0\n", ["robots.workspaces", "belt.length"]
    ),
    "overlapping workspaces": toml(
        "[robots]\ncount = 2\nworkspaces = [[0.3, 0.9], [0.8, 1.2]]\n",
        ["robots.workspaces", "overlap"],
    ),
    "workspaces for the wrong count": toml(
        "[robots]\nworkspaces = [[0.3, 0.9]]\n", ["robots.workspaces", "robots.count = 4"]
    ),
    "override of robot 9": toml(
        "[[robots.overrides]]\nrobot = 9\narm_speed = 4.0\n",
        ["robots.overrides.robot", "9", "1..4"],
    ),
    "override twice": toml(
        "[[robots.overrides]]\nrobot = 2\n[[robots.overrides]]\nrobot = 2\n", ["robot 2", "twice"]
    ),
    "warm-up past the end": toml("duration = 50.0\nwarmup = 60.0\n", ["warmup", "duration"]),
    "breakdowns without repair": toml("[robots]\nmtbf = 100.0\n", ["robots.mttr"]),
    "one robot breaks without repair": toml(
        "[[robots.overrides]]\nrobot = 1\nmtbf = 5.0\n", ["robots.overrides", "robot 1", "mttr"]
    ),
    "unknown policy in the file": toml('policy = "FASTEST"\n', ["policy", "FASTEST", "SPT"]),
    # --- --set -------------------------------------------------------------------------------
    "--set without =": sets("robots.count", ["--set", "robots.count", "path.to.field=value"]),
    "--set unknown key": sets("belt.spede=1", ["belt.spede", "unknown"]),
    "--set into a value": sets("belt.speed.max=1", ["belt.speed", "not a section"]),
    "--set text for a number": sets("duration=soon", ["duration", "soon", "number"]),
    "--set warm-up past the end": sets("warmup=900", ["warmup", "900", "duration"]),
    "--set source_dir": sets("source_dir=/etc", ["source_dir", "not a scenario field"]),
    "--set count=true": sets("robots.count=true", ["robots.count", "True", "integer"]),
    "--set count=0": sets("robots.count=0", ["robots.count", "greater than or equal to 1"]),
    "--set rate=1e12": sets("feeder.rate=1e12", ["feeder.rate", "1e+12", "1000 parts/s"]),
    "--set bin_offset=[nan, inf]": sets(
        "robots.bin_offset=[nan, inf]", ["robots.bin_offset", "nan", "finite"]
    ),
    "--set lateral_sd=5": sets("feeder.lateral_sd=5", ["feeder.lateral_sd", "wider"], "validate"),
    "--set a trace on poisson": sets("feeder.trace=x.csv", ["feeder.trace", "arrival"]),
    "--set duration=1e6": sets(
        "duration=1e6", ["duration", "2,000,000 parts", "--force"], name="paper_baseline"
    ),
    "--set rate=1000 for an hour": Case(
        ["run", "paper_baseline", "--set", "feeder.rate=1000", "--set", "duration=3600"],
        ["3600 s at 1000 parts/s", "--force"],
    ),
    "--set a policy that is no rule": sets("policy=FASTEST", ["policy", "FASTEST"], "validate"),
    "--set a long bad value": sets("name=" + "x" * 400, ["name", "more characters"]),
    # --- trace files -------------------------------------------------------------------------
    "trace file missing": Case(
        ["run", "tr.toml"],
        ["feeder.trace", "gone.csv"],
        {"tr.toml": '[feeder]\narrival = "trace"\ntrace = "gone.csv"\n'},
    ),
    "trace not given": toml('[feeder]\narrival = "trace"\n', ["feeder.trace", "required"]),
    "trace empty": trace_case("", ["is empty"]),
    "trace header only": trace_case("time,y\n", ["header but no rows"], "validate"),
    "trace without header": trace_case("0.5,0.1\n0.7,0.2\n", ["line 1", "header"]),
    "trace unknown column": trace_case("time,y,v\n0.5,0.1,2\n", ["line 1", "unknown column"]),
    "trace short row": trace_case("time,y\n0.1,0.2\n0.3\n", ["line 3", "1 values"]),
    "trace non-numeric": trace_case("time,y\n0.1,0.2\nx,0.1\n", ["line 3", "non-numeric"]),
    "trace NaN time": trace_case("time,y\n0.1,0.2\nnan,0.1\n", ["line 3", "not a finite"]),
    "trace NaN y": trace_case("time,y\n0.1,nan\n", ["line 2", "y nan"], "validate"),
    "trace negative time": trace_case("time,y\n-0.1,0.2\n", ["line 2", "negative"]),
    "trace out of order": trace_case(
        "time,y\n0.8,0.2\n0.1,0.1\n", ["line 3", "non-decreasing"], "validate"
    ),
    "trace off the belt": trace_case("time,y\n0.5,0.9\n", ["line 2", "outside the belt"]),
    "trace not UTF-8": trace_case(b"time,y\n0.5,0.1\n\xe9,0.2\n", ["not UTF-8", "line 3"]),
    "trace shorter than the run": Case(
        ["run", "line.yaml", "--set", "duration=600"],
        ["duration", "t.csv", "3 parts from 0.1 to 0.9 s", "--set duration="],
        {"line.yaml": TRACE_LINE, "t.csv": TRACE},
    ),
    "trace before the window": Case(
        ["run", "line.yaml", "--set", "warmup=0.95"],
        ["warmup", "no part of the trace"],
        {"line.yaml": TRACE_LINE, "t.csv": TRACE},
    ),
    "shipped trace run too long": sets(
        "duration=600", ["duration", "sample_line.csv"], name="trace_replay"
    ),
    # --- run / validate / schema options -----------------------------------------------------
    "unknown policy": Case(["run", "two_robot", "--policy", "nearest"], ["NEAREST", "FIFO"]),
    "mix of wrong length": Case(
        ["run", "paper_baseline", "--policy", "SD,SD,FIFO"], ["SD,SD,FIFO", "3 rules for 4 robots"]
    ),
    "unknown policy kind": Case(["run", "two_robot", "--policy", "magic:x"], ["magic"]),
    "hdqn folder missing": Case(["run", "two_robot", "--policy", "hdqn:nothere"], ["nothere"]),
    "bad events suffix": Case(
        ["run", "two_robot", "--events", "parts.xlsx"], ["--events", "parts.xlsx", ".csv, .parquet"]
    ),
    "bad spans suffix": Case(["run", "two_robot", "--spans", "spans"], ["--spans", ".csv"]),
    "events path is a folder": Case(
        ["run", "two_robot", "--events", "out.csv"],
        ["--events", "out.csv", "folder"],
        {"out.csv/keep": ""},
    ),
    "events and spans one file": Case(
        ["run", "two_robot", "--events", "a.csv", "--spans", "a.csv"], ["--spans", "a.csv"]
    ),
    "negative seed": Case(["run", "two_robot", "--seed", "-3"], ["--seed"]),
    "unknown option": Case(["run", "two_robot", "--fast"], ["--fast"]),
    "missing argument": Case(["validate"], ["SCENARIO"]),
    "unknown format": Case(["validate", "two_robot", "--format", "json"], ["--format"]),
    "unknown command": Case(["simulate", "two_robot"], ["simulate"]),
    "schema into a folder": Case(["schema", "--out", "dir"], ["--out", "dir"], {"dir/keep": ""}),
    "schema unknown option": Case(["schema", "--pretty"], ["--pretty"]),
    # --- studies: sweep, size, mix -----------------------------------------------------------
    "sweep -r 0": Case(["sweep", "paper_27", "--out", "o", "-r", "0"], ["--replications", "0"]),
    "sweep -r 1": Case(
        ["sweep", "paper_27", "--out", "o", "-r", "1"], ["--replications", "at least 2"]
    ),
    "sweep -r many": Case(["sweep", "paper_27", "--out", "o", "-r", "many"], ["many"]),
    "sweep SD and sd": Case(
        ["sweep", "paper_27", "--out", "o", "--policy", "SD", "--policy", "sd"],
        ["'sd' is 'SD' again"],
    ),
    "sweep unknown policy": Case(
        ["sweep", "paper_27", "--out", "o", "--policy", "NOPE", *SHORT], ["NOPE"]
    ),
    "sweep 1000 x 1000": Case(
        ["sweep", "paper_baseline", "--out", "o", "--set", BIG_GRID],
        ["sweep.grid", "1000 x 1000", "--force"],
    ),
    "sweep of 1e6 s runs": Case(
        ["sweep", "paper_27", "--out", "o", "--set", "sweep.duration=1e6"],
        ["sweep.duration", "--force"],
    ),
    "sweep --out is a file": Case(
        ["sweep", "paper_27", "--out", "o.txt", *SHORT], ["--out", "o.txt"], {"o.txt": "keep"}
    ),
    "sweep unknown backend": Case(
        ["sweep", "paper_27", "--out", "o", "--backend", "spark"], ["--backend"]
    ),
    "sweep of an unknown path": Case(
        ["sweep", "paper_baseline", "--out", "o", "--set", "sweep.grid={'belt.spede': [1.0]}"],
        ["sweep.grid", "belt.spede"],
    ),
    "sweep of the seed": Case(
        ["sweep", "paper_baseline", "--out", "o", "--set", "sweep.grid={'seed': [1, 2]}"],
        ["seed", "cannot be swept"],
    ),
    "sweep to a bad point": Case(
        [
            "sweep",
            "paper_baseline",
            "--out",
            "o",
            "--set",
            "sweep.grid={'belt.speed': [0.8, -1.0]}",
        ],
        ["belt.speed", "-1"],
    ),
    "sweep with an empty list": Case(
        ["sweep", "paper_baseline", "--out", "o", "--set", "sweep.grid={'belt.speed': []}"],
        ["sweep.grid", "empty"],
    ),
    "policies SD and sd in the file": Case(
        ["sweep", "s.toml", "--out", "o"],
        ["sweep.policies", "'sd' is 'SD' again"],
        {"s.toml": '[sweep]\npolicies = ["SD", "sd"]\n'},
    ),
    "replications 0 in the file": Case(
        ["sweep", "s.toml", "--out", "o"],
        ["sweep.replications"],
        {"s.toml": "[sweep]\nreplications = 0\n"},
    ),
    "size -r 1": Case(
        ["size", "sizing_example", "--out", "o", "-r", "1"], ["--replications", "at least 2"]
    ),
    "size target 150": Case(
        ["size", "sizing_example", "--out", "o", "--target", "150", *SHORT], ["--target", "150"]
    ),
    "size confidence 1.5": Case(
        ["size", "sizing_example", "--out", "o", "--confidence", "1.5", *SHORT], ["--confidence"]
    ),
    "size without a target": Case(["size", "two_robot", "--out", "o", *SHORT], ["--target"]),
    "size sweep.target 150": Case(
        ["size", "s.toml", "--out", "o"], ["sweep.target"], {"s.toml": "[sweep]\ntarget = 150.0\n"}
    ),
    "size unknown layout": Case(
        ["size", "sizing_example", "--out", "o", "--layout", "tall", *SHORT], ["--layout"]
    ),
    "mix -r 1": Case(["mix", "rule_mix", "--out", "o", "-r", "1"], ["at least 2"]),
    "mix unknown rule": Case(
        ["mix", "rule_mix", "--out", "o", "--rules", "SD,NOPE", *SHORT], ["NOPE"]
    ),
    "design of a missing file": Case(
        ["design", "nothere.toml", "--target", "90", "--out", "o"], ["nothere.toml"]
    ),
    "capacity of a missing file": Case(
        ["capacity", "nothere.toml", "--target", "90", "--out", "o"], ["nothere.toml"]
    ),
    "headroom of a missing file": Case(
        ["headroom", "nothere.toml", "--out", "o"], ["nothere.toml"]
    ),
    "tune of a missing file": Case(["tune", "nothere.toml", "--out", "o"], ["nothere.toml"]),
    "tune of an unknown strategy": Case(
        ["tune", "paper_baseline", "--strategy", "zigzag", "--out", "o"], ["zigzag", "share, lane"]
    ),
    "a share policy of the wrong length": Case(
        ["run", "paper_baseline", "--policy", "share:50,100", *SHORT], ["2 shares for 4 robots"]
    ),
    "a lane policy with a gap": Case(
        ["run", "paper_baseline", "--policy", "lane:0-0.1,0.2-0.3,0.3-0.35,0.35-0.4", *SHORT],
        ["gap from y = 0.1 to 0.2 m"],
    ),
    "task score of an unknown task": Case(
        ["task", "score", "nosuch", "--policy", "SD"], ["nosuch", "baseline"]
    ),
    "task score with one seed": Case(
        ["task", "score", "baseline", "--policy", "SD", "--seeds", "1"], ["--seeds", "2 to 20"]
    ),
    "task score of an unknown policy": Case(
        ["task", "score", "baseline", "--policy", "NOPE"], ["NOPE"]
    ),
    # --- study folders: report, export -------------------------------------------------------
    "report of a missing folder": Case(["report", "nothere"], ["nothere"]),
    "report of a file": Case(["report", "f.txt"], ["f.txt"], {"f.txt": "keep"}),
    "report of an empty folder": Case(["report", "empty"], ["empty"], {"empty/keep": ""}),
    "report of a corrupt study": Case(
        ["report", "st"], ["st"], {"st/study.json": "{not json", "st/meta.json": "{"}
    ),
    "export of a missing folder": Case(["export", "nothere", "--xlsx", "t.xlsx"], ["nothere"]),
    "export of a folder that is no study": Case(
        ["export", "st", "--xlsx", "t.xlsx"], ["st"], {"st/keep": ""}
    ),
    # --- training and evaluation -------------------------------------------------------------
    "train an empty scenario": Case(
        ["train", "e.toml", "--out", "m"], ["e.toml", "is empty"], {"e.toml": ""}
    ),
    "train --steps 0": Case(["train", "two_robot", "--out", "m", "--steps", "0"], ["--steps"]),
    "train unknown mode": Case(["train", "two_robot", "--out", "m", "--mode", "solo"], ["--mode"]),
    "train count=true": Case(
        ["train", "two_robot", "--out", "m", "--set", "robots.count=true"], ["robots.count", "True"]
    ),
    "train unknown rule": Case(
        ["train", "two_robot", "--out", "m", "--rules", "SD,NOPE"], ["NOPE"]
    ),
    "evaluate a missing model": Case(
        ["evaluate", "two_robot", "--policy", "hdqn:nothere"], ["nothere"]
    ),
    "evaluate one seed": Case(
        ["evaluate", "two_robot", "--policy", "hdqn:m", "--seeds", "1"], ["--seeds"]
    ),
    "evaluate a non-UTF-8 scenario": Case(
        ["evaluate", "s.toml", "--policy", "hdqn:m"],
        ["s.toml", "not UTF-8"],
        {"s.toml": b"name = '\xff'\n"},
    ),
    # --- calibration -------------------------------------------------------------------------
    "calibrate missing targets": Case(
        [
            "calibrate",
            "two_robot",
            "--targets",
            "gone.csv",
            "--out",
            "c",
            "--fit",
            "robots.pick_time=0:0.3",
        ],
        ["gone.csv"],
    ),
    "calibrate a fit without bounds": Case(
        ["calibrate", "two_robot", "--targets", "t.csv", "--out", "c", "--fit", "robots.pick_time"],
        ["--fit", "robots.pick_time"],
        {"t.csv": "feeder.rate,gripping_rate\n4,90\n"},
    ),
    "calibrate an unknown field": Case(
        ["calibrate", "two_robot", "--targets", "t.csv", "--out", "c", "--fit", "robots.grip=0:1"],
        ["robots.grip"],
        {"t.csv": "feeder.rate,gripping_rate\n4,90\n"},
    ),
    "calibrate targets without a KPI": Case(
        [
            "calibrate",
            "two_robot",
            "--targets",
            "t.csv",
            "--out",
            "c",
            "--fit",
            "robots.pick_time=0:0.3",
        ],
        ["t.csv"],
        {"t.csv": "feeder.rate\n4\n"},
    ),
    "calibrate non-UTF-8 targets": Case(
        [
            "calibrate",
            "two_robot",
            "--targets",
            "t.csv",
            "--out",
            "c",
            "--fit",
            "robots.pick_time=0:0.3",
        ],
        ["t.csv"],
        {"t.csv": b"feeder.rate,gripping_rate\n4,\xff\n"},
    ),
}

SUBPROCESS = [
    "billion laughs",
    "non-UTF-8 TOML",
    "trace NaN time",
    "--set duration=1e6",
    "--set source_dir",
    "sweep 1000 x 1000",
    "size -r 1",
    "report of a corrupt study",
    "train an empty scenario",
    "calibrate non-UTF-8 targets",
]


def write_files(root: Path, files: dict[str, str | bytes]) -> None:
    (root / "existing-output.csv").write_text("a,b\n1,2\n", encoding="utf-8")  # a sentinel
    for name, content in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")


def snapshot(root: Path) -> dict[str, tuple[str, int]]:
    """Every file under ``root``: its content hash and modification time."""
    return {
        str(p.relative_to(root)): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def check_answer(
    case: Case, code: int, stdout: str, stderr: str, seconds: float, limit: float = SECONDS
) -> None:
    assert code == 2, (code, stdout, stderr)
    assert stdout == "", stdout
    assert "Traceback" not in stderr, stderr
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    line = lines[0]
    assert line.startswith("error: "), line
    assert len(line) <= MAX_LINE, f"{len(line)} characters: {line}"
    for needle in case.needles:
        assert needle in line, f"{needle!r} not in {line!r}"
    assert seconds < limit, f"{seconds:.1f} s"


@contextmanager
def alarm(seconds: int) -> Iterator[None]:
    """Fail, rather than hang, when the block runs past ``seconds``."""

    def ring(signum: int, frame: object) -> None:
        raise TimeoutError(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, ring)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    case = CASES[name]
    write_files(tmp_path, case.files)
    before = snapshot(tmp_path)
    monkeypatch.chdir(tmp_path)
    t0 = time.perf_counter()
    with alarm(int(3 * SECONDS)):
        result = CliRunner().invoke(app, case.args)
    seconds = time.perf_counter() - t0
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"{name}: {result.exception!r}") from result.exception
    check_answer(case, result.exit_code, result.stdout, result.stderr, seconds)
    assert snapshot(tmp_path) == before, "a failed command changed or wrote files"


@pytest.mark.parametrize("name", SUBPROCESS)
def test_bad_input_as_a_process(name: str, tmp_path: Path) -> None:
    case = CASES[name]
    write_files(tmp_path, case.files)
    before = snapshot(tmp_path)
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "pnp_twin", *case.args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=60,
    )
    seconds = time.perf_counter() - t0
    check_answer(case, done.returncode, done.stdout, done.stderr, seconds, PROCESS_SECONDS)
    assert snapshot(tmp_path) == before


def test_the_suite_covers_every_command_and_at_least_80_cases() -> None:
    commands = {c.args[0] for c in CASES.values()}
    listed = {c.name for c in app.registered_commands if c.name} - {"list"}
    assert listed <= commands, listed - commands
    assert len(CASES) >= 80


@pytest.mark.parametrize(
    "args",
    [
        ["run", "two_robot", "--set", "duration=20", "--set", "warmup=2"],
        ["sweep", "paper_baseline", "--out", "o", "--no-report", "--workers", "1", "-r", "2",
         "--set", "sweep.grid={'feeder.rate': [8.0]}", "--policy", "SD", *SHORT],
    ],
    ids=["run", "sweep"],
)  # fmt: skip
def test_force_goes_ahead_above_the_limit(
    args: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("pnp_twin.twin.budget.MAX_PARTS", 10)  # every run is now "too large"
    refused = CliRunner().invoke(app, args)
    assert refused.exit_code == 2 and "--force" in refused.stderr
    forced = CliRunner().invoke(app, [*args, "--force"])
    assert forced.exit_code == 0, forced.output
