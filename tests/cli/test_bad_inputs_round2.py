"""Bad inputs, round two: the classes issue 18 found handled badly, in TOML and YAML.

Every case runs one command in an empty folder and asserts the contract of
``test_bad_inputs``: exit code 2, nothing on stdout, exactly one ``error:`` line naming the
file / field / row (the needles) and what is allowed, no traceback, an answer within a few
seconds, and nothing written, changed or created (not even an empty folder). The classes:

- hangs: no physical lower bound on a speed or rate (``belt.speed = 1e-300``); inputs that
  are not regular files (a FIFO, a link to ``/dev/zero``, a folder) read instead of refused;
- data loss: an output written onto an input (``--events`` onto the trace, a study folder
  holding its own scenario or targets);
- silent nonsense: YAML duplicate keys, YAML 1.1 scalars (``yes``, ``NO``, ``1e3``, ``010``),
  calibration targets out of their range, ``calibrate --workers 0``, a repeated grid value,
  ``mix --rules ""``;
- written on refusal: every ``size`` / ``mix`` / ``sweep`` / ``calibrate`` refusal before the
  output folder exists;
- where output goes: ``--out /`` or a folder of other files;
- unclear lines: file kinds, list shapes, list indexes, duplicated CSV columns.
"""

from __future__ import annotations

import hashlib
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from tests.cli.test_bad_inputs import SECONDS, alarm, check_answer

TRACE = "time,y\n0.1,0.2\n0.5,0.1\n0.9,0.3\n"
TRACE_LINE = "feeder: {arrival: trace, trace: t.csv}\nduration: 1.0\nwarmup: 0.0\n"
SHORT = ["--set", "sweep.duration=20", "--set", "sweep.warmup=2"]
TARGETS = "robots.arm_speed,gripping_rate\n2,60\n3,80\n"
FIT = ["--fit", "robots.pick_time=0:0.3"]


def fifo(name: str) -> Callable[[Path], None]:
    return lambda root: os.mkfifo(root / name)


def link(name: str, to: str) -> Callable[[Path], None]:
    return lambda root: os.symlink(to, root / name)


def hard_link(name: str, to: str) -> Callable[[Path], None]:
    return lambda root: os.link(root / to, root / name)


@dataclass(frozen=True)
class Case:
    """One bad input: files to write, file kinds to make, the command, what it must name."""

    args: list[str]
    needles: list[str]
    files: dict[str, str | bytes] = field(default_factory=dict)
    make: tuple[Callable[[Path], None], ...] = ()


def toml(text: str, needles: list[str], command: str = "validate") -> Case:
    return Case([command, "s.toml"], needles, {"s.toml": text})


def yaml(text: str, needles: list[str], command: str = "validate") -> Case:
    return Case([command, "s.yaml"], needles, {"s.yaml": text})


def calibrate(*extra: str) -> list[str]:
    return ["calibrate", "two_robot", "--targets", "t.csv", "--out", "c", *FIT, *extra]


def cal(needles: list[str], *extra: str, targets: str = TARGETS, **kw: Any) -> Case:
    files = {"t.csv": targets, **kw.pop("files", {})}
    return Case(calibrate(*extra), needles, files, **kw)


CASES: dict[str, Case] = {
    # --- hangs: physical lower bounds, in TOML, YAML and --set --------------------------------
    "belt.speed 1e-300 (TOML)": toml(
        "[belt]\nspeed = 1e-300\n", ["belt.speed", "1e-300", "at least 0.01 m/s"], "run"
    ),
    "belt.speed 1e-300 (YAML)": yaml(
        "belt:\n  speed: 1.0e-300\n", ["belt.speed", "at least 0.01 m/s"], "run"
    ),
    "feeder.rate 1e-300": Case(
        ["run", "two_robot", "--set", "feeder.rate=1e-300"], ["feeder.rate", "0.001 parts/s"]
    ),
    "arm speed 1e-300 in an override": toml(
        "[[robots.overrides]]\nrobot = 1\narm_speed = 1e-300\n", ["arm_speed", "0.01 m/s"]
    ),
    "mtbf 1e-300": yaml(
        "robots:\n  mtbf: 1.0e-300\n  mttr: 1.0\n", ["robots.mtbf", "0 (off) or at least 0.1 s"]
    ),
    "workspace 1e-300 m": toml(
        "[robots]\nworkspace_length = 1e-300\n", ["robots.workspace_length", "0.001 m"]
    ),
    "belt width 1e-300 m": toml("[belt]\nwidth = 1e-300\n", ["belt.width", "0.001 m"]),
    "--half-width 1e-300": Case(
        ["sweep", "paper_27", "--out", "o", "-r", "auto", "--half-width", "1e-300"],
        ["half_width", "0.01"],
    ),
    # --- hangs and unclear lines: inputs that are not regular files ---------------------------
    "trace links to /dev/zero": Case(
        ["run", "line.yaml"],
        ["feeder.trace", "t.csv", "character device", "/dev/zero"],
        {"line.yaml": TRACE_LINE},
        (link("t.csv", "/dev/zero"),),
    ),
    "trace is a FIFO": Case(
        ["validate", "line.yaml"],
        ["feeder.trace", "t.csv", "FIFO"],
        {"line.yaml": TRACE_LINE},
        (fifo("t.csv"),),
    ),
    "trace with a column twice": Case(
        ["run", "line.yaml"],
        ["feeder.trace", "t.csv", "line 1", "'y' twice"],
        {"line.yaml": TRACE_LINE, "t.csv": "time,y,y\n0.1,0.2,0.2\n"},
    ),
    "trace is a folder": Case(
        ["run", "line.yaml"],
        ["feeder.trace", "t.csv", "folder"],
        {"line.yaml": TRACE_LINE, "t.csv/x": ""},
    ),
    "scenario is a FIFO": Case(
        ["run", "s.toml"], ["scenario", "s.toml", "FIFO"], make=(fifo("s.toml"),)
    ),
    "scenario links to /dev/zero": Case(
        ["validate", "s.yaml"], ["s.yaml", "character device"], make=(link("s.yaml", "/dev/zero"),)
    ),
    "scenario is a folder named .toml": Case(
        ["run", "d.toml"], ["d.toml", "a folder"], {"d.toml/x": ""}
    ),
    "targets link to /dev/zero": Case(
        ["calibrate", "two_robot", "--targets", "z.csv", "--out", "c", *FIT],
        ["--targets", "z.csv", "character device"],
        make=(link("z.csv", "/dev/zero"),),
    ),
    "targets are a FIFO": Case(
        ["calibrate", "two_robot", "--targets", "f.csv", "--out", "c", *FIT],
        ["--targets", "f.csv", "FIFO"],
        make=(fifo("f.csv"),),
    ),
    # --- data loss: outputs onto inputs -------------------------------------------------------
    "--events onto the trace": Case(
        ["run", "line.yaml", "--events", "t.csv"],
        ["--events", "t.csv", "trace"],
        {"line.yaml": TRACE_LINE, "t.csv": TRACE},
    ),
    "--spans onto a hard link of the trace": Case(
        ["run", "line.yaml", "--spans", "h.csv"],
        ["--spans", "h.csv", "trace"],
        {"line.yaml": TRACE_LINE, "t.csv": TRACE},
        (hard_link("h.csv", "t.csv"),),
    ),
    "--events onto the trace through ..": Case(
        ["run", "line.yaml", "--events", "sub/../t.csv"],
        ["--events", "trace"],
        {"line.yaml": TRACE_LINE, "t.csv": TRACE, "sub/keep": ""},
    ),
    "sweep into the folder holding its scenario": Case(
        ["sweep", "o/s.toml", "--out", "o", *SHORT],
        ["--out o", "scenario file", "s.toml"],
        {"o/study.json": "{}", "o/s.toml": "[robots]\ncount = 2\n"},
    ),
    "calibrate into the folder holding its targets": Case(
        ["calibrate", "two_robot", "--targets", "c/t.csv", "--out", "c", *FIT],
        ["--out c", "targets file"],
        {"c/t.csv": TARGETS, "c/evals/keep": ""},
    ),
    "report --out onto a study table": Case(
        ["report", "st", "--out", "st/results.csv"], ["--out", ".html"], {"st/study.json": "{}"}
    ),
    # --- silent nonsense: YAML ----------------------------------------------------------------
    "YAML duplicate key": yaml(
        "belt:\n  speed: 0.5\n  speed: 0.6\n", ["s.yaml", "speed", "twice", "line 3"]
    ),
    "YAML duplicate section": yaml(
        "robots:\n  count: 2\nbelt:\n  speed: 0.5\nrobots:\n  count: 3\n",
        ["s.yaml", "robots", "twice"],
    ),
    "YAML duplicate key in a flow mapping": yaml(
        "belt: {speed: 0.5, speed: 0.6}\n", ["s.yaml", "speed", "twice"]
    ),
    "YAML count: on": yaml(
        "robots:\n  count: on\n", ["s.yaml", "robots.count", "on", "True", "YAML 1.2"]
    ),
    "YAML policy: NO": yaml("policy: NO\n", ["s.yaml", "policy", "NO", "False", "quote it"]),
    "YAML 1e3": yaml(
        "belt:\n  length: 1e3\n", ["s.yaml", "belt.length", "1e3", "YAML 1.1", "1000.0"]
    ),
    "YAML 1e-300 without a dot": yaml(
        "belt:\n  speed: 1e-300\n", ["belt.speed", "1e-300", "1.0e-300"]
    ),
    "YAML octal 010": yaml("seed: 010\n", ["seed", "010", "8", "10"]),
    "YAML sexagesimal 10:00": yaml("duration: 10:00\n", ["duration", "10:00", "600"]),
    "YAML 1_000": yaml("duration: 1_000\n", ["duration", "1_000"]),
    "YAML key yes": yaml("belt:\n  yes: 1.0\n", ["belt", "yes"]),
    "YAML ambiguous in a list": yaml(
        "robots:\n  bin_offset: [0.0, 5e-1]\n", ["robots.bin_offset.1", "5e-1"]
    ),
    # --- silent nonsense: calibration targets, options, grids, rules --------------------------
    "targets gripping rate 150": cal(
        ["t.csv", "row 2", "gripping_rate", "150", "0..100"],
        targets="robots.arm_speed,gripping_rate\n2,60\n3,150\n",
    ),
    "targets gripping rate -5": cal(
        ["row 1", "gripping_rate", "-5", "0..100"],
        targets="robots.arm_speed,gripping_rate\n2,-5\n3,80\n",
    ),
    "targets efficiency in %": cal(
        ["efficiency", "85", "0..1"], targets="robots.arm_speed,efficiency\n2,85\n"
    ),
    "targets throughput inf": cal(
        ["throughput", "inf", ">= 0"], targets="robots.arm_speed,throughput\n2,inf\n"
    ),
    "targets weight inf": cal(
        ["weight", "inf"], targets="robots.arm_speed,gripping_rate,weight\n2,60,inf\n"
    ),
    "targets duplicated column": cal(
        ["t.csv", "line 2", "gripping_rate", "twice"],
        targets="# source\nrobots.arm_speed,gripping_rate,gripping_rate\n2,60,61\n",
    ),
    "calibrate --workers 0": cal(["--workers", "greater than or equal to 1"], "--workers", "0"),
    "calibrate --workers -3": cal(["--workers", "greater than or equal to 1"], "--workers", "-3"),
    "calibrate -r 1e20": cal(["--replications"], "-r", "99999999999999999999"),
    "calibrate above the work limit": cal(["--replications", "runs", "--force"], "-r", "10000"),
    "sweep grid 4 and 4.0": Case(
        ["sweep", "two_robot", "--out", "o", "--set", "sweep.grid={feeder.rate: [4, 4.0]}", *SHORT],
        ["sweep.grid.feeder.rate", "twice"],
    ),
    "sweep grid repeated in the file": Case(
        ["sweep", "s.toml", "--out", "o"],
        ["sweep.grid.robots.arm_speed", "2", "twice"],
        {"s.toml": '[sweep.grid]\n"robots.arm_speed" = [2.0, 3.0, 2.0]\n'},
    ),
    "mix --rules ''": Case(
        ["mix", "rule_mix", "--out", "o", "--rules", "", *SHORT], ["--rules", "names no rule"]
    ),
    "mix --rules ,": Case(["mix", "rule_mix", "--out", "o", "--rules", ",", *SHORT], ["--rules"]),
    "mix --rules SD,,FIFO": Case(
        ["mix", "rule_mix", "--out", "o", "--rules", "SD,,FIFO", *SHORT], ["--rules", "empty name"]
    ),
    # --- written on refusal: refused before the folder exists ---------------------------------
    "size --target 0": Case(
        ["size", "sizing_example", "--out", "o", "--target", "0", *SHORT], ["--target", "0"]
    ),
    "size --target -5": Case(
        ["size", "sizing_example", "--out", "o", "--target", "-5", *SHORT], ["--target", "-5"]
    ),
    "size --target nan": Case(
        ["size", "sizing_example", "--out", "o", "--target", "nan", *SHORT], ["--target", "nan"]
    ),
    "size --confidence 0": Case(
        ["size", "sizing_example", "--out", "o", "--confidence", "0", *SHORT], ["--confidence", "0"]
    ),
    "size --confidence 1": Case(
        ["size", "sizing_example", "--out", "o", "--confidence", "1", *SHORT], ["--confidence", "1"]
    ),
    "size share with too wide gaps": Case(
        [
            "size",
            "sizing_example",
            "--out",
            "o",
            "--layout",
            "share",
            "--set",
            "robots.workspace_gap=0.5",
            *SHORT,
        ],
        ["--layout share"],
    ),
    "mix --budget 0": Case(
        ["mix", "rule_mix", "--out", "o", "--budget", "0", *SHORT], ["--budget", "0"]
    ),
    "mix --budget -1": Case(
        ["mix", "rule_mix", "--out", "o", "--budget", "-1", *SHORT], ["--budget", "-1"]
    ),
    "mix of per-robot mixes": Case(
        [
            "mix",
            "rule_mix",
            "--out",
            "o",
            "--set",
            "robots.count=2",
            "--set",
            "sweep.policies=['SPT,SPT,SPT,FIFO']",
            *SHORT,
        ],
        ["SPT,SPT,SPT,FIFO", "not a rule"],
    ),  # fmt: skip
    "mix of a rule twice": Case(
        ["mix", "rule_mix", "--out", "o", "--rules", "SD,sd", *SHORT], ["twice"]
    ),
    "sweep grid over policy": Case(
        ["sweep", "two_robot", "--out", "o", "--set", "sweep.grid={policy: [SD, FIFO]}", *SHORT],
        ["policy", "cannot be swept", "sweep.policies"],
    ),
    "calibrate a robot the line lacks": cal(
        ["r9_throughput", "robot 9", "2 robots"],
        targets="robots.arm_speed,gripping_rate,r9_throughput\n2,60,1.0\n",
    ),
    # --- where output goes ---------------------------------------------------------------------
    "sweep --out a folder of other files": Case(
        ["sweep", "two_robot", "--out", "o", *SHORT],
        ["--out o", "notes.txt"],
        {"o/notes.txt": "mine"},
    ),
    "size --out a folder of other files": Case(
        ["size", "sizing_example", "--out", "o", *SHORT], ["--out o", "a.csv"], {"o/a.csv": "1"}
    ),
    "mix --out a folder of other files": Case(
        ["mix", "rule_mix", "--out", "o", *SHORT], ["--out o", "x"], {"o/x": ""}
    ),
    "calibrate --out a folder of other files": cal(
        ["--out c", "thesis.tex"], files={"c/thesis.tex": "x"}
    ),
    "sweep --out a FIFO": Case(
        ["sweep", "two_robot", "--out", "p", *SHORT], ["--out p", "FIFO"], make=(fifo("p"),)
    ),
    "--events in a new folder, scenario refused": Case(
        ["run", "s.toml", "--events", "new/deeper/parts.csv"],
        ["belt.speed"],
        {"s.toml": "[belt]\nspeed = -1.0\n"},
    ),
    "--events under a file": Case(
        ["run", "two_robot", "--events", "f.txt/parts.csv"], ["--events", "f.txt"], {"f.txt": "x"}
    ),
    # --- unclear lines -------------------------------------------------------------------------
    "bin_offset of one number (TOML)": toml(
        "[robots]\nbin_offset = [0.0]\n", ["robots.bin_offset", "[0.0]", "two numbers [dx, dy]"]
    ),
    "bin_offset of three numbers (YAML)": yaml(
        "robots:\n  bin_offset: [0.0, 0.5, 0.1]\n", ["robots.bin_offset", "two numbers [dx, dy]"]
    ),
    "bin_offset of a number": toml(
        "[robots]\nbin_offset = 3.0\n", ["robots.bin_offset", "[dx, dy]"]
    ),
    "override bin_offset of one number": toml(
        "[[robots.overrides]]\nrobot = 1\nbin_offset = [0.3]\n",
        ["robots.overrides.0.bin_offset", "[dx, dy]"],
    ),
    "grid of one number": yaml("belt:\n  grid: [64]\n", ["belt.grid", "two whole numbers"]),
    "a workspace of one number": toml(
        "[robots]\ncount = 2\nworkspaces = [[0.3], [0.5, 0.9]]\n",
        ["robots.workspaces.0", "two numbers [a, b]"],
    ),
    "--set an index out of range": Case(
        ["validate", "two_robot", "--set", "robots.bin_offset.7=0.1"],
        ["robots.bin_offset.7", "out of range", "0..1"],
    ),
    "--set an index of an unset list": Case(
        ["validate", "two_robot", "--set", "robots.workspaces.0.1=0.5"],
        ["robots.workspaces", "whole list"],
    ),
}


def write_files(root: Path, case: Case) -> None:
    (root / "existing-output.csv").write_text("a,b\n1,2\n", encoding="utf-8")  # a sentinel
    for name, content in case.files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
    for make in case.make:
        make(root)


def snapshot(root: Path) -> dict[str, tuple[str, int]]:
    """Every entry under ``root`` (folders and special files too), with a regular file's
    content hash and modification time: a refusal may create or change nothing."""
    out: dict[str, tuple[str, int]] = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        if p.is_symlink() or not p.is_file():
            out[str(p.relative_to(root))] = ("not a regular file", st.st_mode)
        else:
            out[str(p.relative_to(root))] = (
                hashlib.sha256(p.read_bytes()).hexdigest(),
                st.st_mtime_ns,
            )
    return out


def run_case(case: Case, root: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write_files(root, case)
    before = snapshot(root)
    monkeypatch.chdir(root)
    t0 = time.perf_counter()
    with alarm(int(3 * SECONDS)):
        result = CliRunner().invoke(app, case.args)
    seconds = time.perf_counter() - t0
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"{case.args}: {result.exception!r}") from result.exception
    check_answer(case, result.exit_code, result.stdout, result.stderr, seconds)  # type: ignore[arg-type]
    assert snapshot(root) == before, "a refused command created, changed or wrote something"


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_round_two(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run_case(CASES[name], tmp_path, monkeypatch)


def test_out_slash_is_refused_and_never_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--out /``: refused (it holds other files, and the shipped scenario the command
    reads). Guarded, so that a regression fails here without writing a study into the
    machine's root."""

    def guard(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("a study was opened in /")

    monkeypatch.setattr("pnp_twin.studies.runner.open_session", guard)
    monkeypatch.setattr("pnp_twin.studies.lock.StudyLock", guard)
    root = set(os.listdir("/"))
    for args in (
        ["sweep", "two_robot", "--out", "/", *SHORT],
        ["size", "sizing_example", "--out", "/", *SHORT],
        ["mix", "rule_mix", "--out", "/", *SHORT],
        ["calibrate", "two_robot", "--targets", "t.csv", "--out", "/", *FIT],
    ):
        case = Case(args, ["--out /:", "keep inputs outside it"], {"t.csv": TARGETS})
        (tmp_path / args[0]).mkdir()
        run_case(case, tmp_path / args[0], monkeypatch)
    assert set(os.listdir("/")) == root


def test_every_round_two_class_has_cases() -> None:
    assert len(CASES) >= 60


# --- the same classes, below the command line ----------------------------------------------


def test_mix_intervals_are_clipped_to_percentages() -> None:
    from pnp_twin.studies.rulemix import rank

    class Search:
        order = ["SD,SD", "FIFO,FIFO"]
        rows = {
            "SD,SD": [
                {"gripping_rate": g, "replication": k} for k, g in enumerate([99.0, 60.0, 100.0])
            ],
            "FIFO,FIFO": [
                {"gripping_rate": g, "replication": k} for k, g in enumerate([1.0, 40.0, 0.0])
            ],
        }

    ranked = rank(Search(), 0.95)  # type: ignore[arg-type]
    for r in ranked:
        assert 0.0 <= r["ci_low"] <= r["gripping_rate_mean"] <= r["ci_high"] <= 100.0, r
    assert ranked[0]["ci_high"] == 100.0 and ranked[1]["ci_low"] == 0.0


def test_a_yaml_file_accepts_what_both_yaml_versions_read_alike(tmp_path: Path) -> None:
    from pnp_twin.twin.loader import load_scenario

    path = tmp_path / "ok.yaml"
    path.write_text(
        "name: '1e3'\ndescription: 'yes'\npolicy: SD\nduration: 1.0e+2\nwarmup: 10\n"
        "belt:\n  speed: 0.8\n  grid: [64, 8]\nrobots:\n  count: 2\n  bin_offset: [0.0, 0.5]\n"
        "feeder:\n  rate: .5\n",
        encoding="utf-8",
    )
    sc = load_scenario(path)
    assert (sc.name, sc.description, sc.duration, sc.feeder.rate) == ("1e3", "yes", 100.0, 0.5)


def test_set_names_one_element_of_a_list() -> None:
    from pnp_twin.twin.loader import load_scenario

    sc = load_scenario("two_robot", {"robots.bin_offset.1": 0.4})
    assert sc.robots.bin_offset[1] == 0.4
    assert sc.robots.bin_offset[0] == load_scenario("two_robot").robots.bin_offset[0]


def test_the_lower_bounds_let_through_the_slowest_real_lines() -> None:
    from pnp_twin.twin.loader import load_scenario

    sc = load_scenario(
        "two_robot",
        {"belt.speed": 0.01, "feeder.rate": 0.001, "robots.mtbf": 1.0, "robots.mttr": 0.001},
    )
    assert sc.belt.speed == 0.01 and math.isclose(sc.feeder.rate, 0.001)


def test_a_checkpoint_weights_path_that_is_a_folder_says_so(tmp_path: Path) -> None:
    from pnp_twin.policies.hdqn.checkpoint import CheckpointError, read_tensors

    (tmp_path / "model.safetensors").mkdir()
    with pytest.raises(CheckpointError, match="is a folder"):
        read_tensors(tmp_path / "model.safetensors")


def test_a_refused_study_leaves_no_folder_even_after_opening_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The last line of defence: a refusal raised once the study's lock has made the folder
    removes the folder it made (and only a folder it made)."""

    def refuse(*args: Any, **kwargs: Any) -> Any:
        from pnp_twin.studies.plan import StudyError

        raise StudyError("refused after the lock")

    monkeypatch.chdir(tmp_path)

    def open_then_refuse(out: Path, *args: Any, **kwargs: Any) -> Any:
        out.mkdir(parents=True, exist_ok=True)
        (out / ".study.lock").write_text("")
        refuse()

    monkeypatch.setattr("pnp_twin.studies.runner.open_session", open_then_refuse)
    args = ["sweep", "two_robot", "--out", "o", "--workers", "1", "--engine", "simpy", *SHORT]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and "refused after the lock" in result.stderr
    assert not (tmp_path / "o").exists()
    (tmp_path / "o").mkdir()  # a folder that was there before stays
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and (tmp_path / "o").is_dir()
