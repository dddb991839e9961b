"""A generative fuzzer of the command line's inputs (hypothesis).

Each example copies the seed corpus (``corpus/``: a line, a replayed trace, a study, measured
targets and the command lines of ``commands.txt``) into an empty folder, mutates one or more
of them (a scenario field's type, bound or length; a file's text, encoding or kind; a trace
or targets row, cell or header; a study section; an option of the command line), runs the
command in-process and asserts the contract every input must meet:

- exit 0 with sane output (JSON that parses, a gripping rate in [0, 100], an efficiency in
  [0, 1]), or exit 2 with nothing on stdout and exactly one ``error:`` line of at most 400
  characters; never another code, never a traceback;
- an answer within :data:`LIMIT` seconds (an alarm turns a hang into a failure);
- on a refusal, nothing written, changed or created; on success, no input changed and nothing
  written outside the outputs the command names (``--out``, ``--events``, ...).

The examples are derandomised (the same cases on every run, so CI is repeatable); set
``PNP_FUZZ_EXAMPLES`` for more and ``PNP_FUZZ_RANDOM=1`` to draw new ones. The work limits of
``twin.budget`` are lowered for the fuzzer, so a mutation that asks for a long run is refused
at once (with ``--force`` named) instead of running for minutes.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shlex
import shutil
import tempfile
import time
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

import pytest
import tomli_w
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from pnp_twin.cli import app
from tests.cli.test_bad_inputs import MAX_LINE, alarm

CORPUS = Path(__file__).parent / "corpus"
EXAMPLES = int(os.environ.get("PNP_FUZZ_EXAMPLES", "120"))
LIMIT = 20.0  # s per case, on a loaded 2-core machine
OUTPUT_OPTIONS = ("--out", "-o", "--events", "--spans", "--report", "--xlsx")
INPUTS = ("line.toml", "replay.yaml", "trace.csv", "study.toml", "targets.csv")


def commands() -> list[list[str]]:
    lines = (CORPUS / "commands.txt").read_text(encoding="utf-8").splitlines()
    return [shlex.split(x) for x in lines if x.strip() and not x.startswith("#")]


COMMANDS = commands()

NASTY: list[Any] = [
    0, -1, 1, 2, 65, 2**63, -(2**63), 10**30, 0.0, -0.0, 1e-300, -1e-300, 5e-324, 1e-9, 1e9,
    1e300, math.inf, -math.inf, math.nan, True, False, "", "10", "yes", "NO", "1e3", "x" * 300,
    "SD,FIFO", "SD,SD,SD", "hdqn:nothere", "\u00e9", "a\nb", "trace", [], [0.0], [1, 2, 3],
    [[0.3, 0.5]], [0.0, 0.25], {}, {"a": 1}, {"speed": 1.0}, "t_all", "poisson", "fixed",
]  # fmt: skip
NASTY_TEXT = [
    "0", "-3", "1", "nan", "inf", "-inf", "", " ", "1e309", "1e-300", "x", "/", "..", "150",
    "SD", "sd,sd", "NOPE", "SD,,FIFO", ",", "auto", "2.5", "0x10", "\u00e9", "line.toml",
    "trace.csv", "targets.csv", "99999999999999999999",
]  # fmt: skip
EXTRA_OPTIONS: list[list[str]] = [
    ["--events", "trace.csv"], ["--spans", "trace.csv"], ["--events", "targets.csv"],
    ["--report", "line.toml"], ["--events", "new/deeper/parts.csv"], ["--out", "/"],
    ["--out", "."], ["--out", "line.toml"], ["--out", "filled"], ["--out", "trace.csv/x"],
    ["--workers", "0"], ["--workers", "-3"], ["--rules", ""], ["--budget", "0"],
    ["--target", "150"], ["--target", "nan"], ["--confidence", "1"], ["--seed", "-1"],
    ["-r", "1"], ["-r", "0"], ["--half-width", "1e-300"], ["--replications", "auto"],
    ["--fit", "robots.pick_time=0:1e300"], ["--fit", "robots.bin_offset.7=0:1"],
    ["--fit", "policy=0:1"], ["--policy", "NOPE"], ["--policy", "SD,SD,SD"], ["--fresh"],
    ["--set", "robots.bin_offset.7=0.1"], ["--set", "belt.speed=1e-300"],
    ["--set", "sweep.grid={policy: [SD, FIFO]}"], ["--set", "sweep.grid={feeder.rate: [2, 2.0]}"],
    ["--set", "sweep.grid={seed: [1, 2]}"], ["--set", "feeder.trace=trace.csv"],
    ["--set", "robots.count=9"], ["--set", "duration=1e6"], ["--set", "sweep.target=0"],
]  # fmt: skip
NASTY_LINES = [
    "speed = 1e-300", "belt:\n  speed: yes", "[belt]", "[belt]\nspeed = 0.5\nspeed = 0.6",
    "robots: {count: on}", "duration: 10:00", "seed: 010", "a: &a [1]\nb: *a", "\t", "\x00",
    "policy = NO", "policy: NO", "[[robots.overrides]]\nrobot = 9", "<<: {x: 1}",
    "belt: {speed: 0.5, speed: 0.6}", "[sweep.grid]\n\"feeder.rate\" = [2.0, 2.0]",
]  # fmt: skip
CELLS = ["nan", "-1", "1e300", "", "x", "0x10", "inf", "150", "-5", "1e-300", "\u00e9", "1,2"]
HEADERS = ["time", "y", "kind", "gripping_rate", "r9_throughput", "efficiency", "weight",
           "policy", "robots.bin_offset.7", "belt.spede", "time"]  # fmt: skip


# --- mutating the files ------------------------------------------------------------------------


def leaves(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path into a nested mapping / list (sections and values alike)."""
    out: list[tuple[Any, ...]] = [prefix] if prefix else []
    if isinstance(data, dict):
        for k, v in data.items():
            out += leaves(v, (*prefix, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out += leaves(v, (*prefix, i))
    return out


def put(data: Any, path: tuple[Any, ...], value: Any, delete: bool = False) -> None:
    node = data
    for key in path[:-1]:
        node = node[key]
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value


def get(data: Any, path: tuple[Any, ...]) -> Any:
    for key in path:
        data = data[key]
    return data


def mutate_mapping(draw: Any, data: dict[str, Any]) -> dict[str, Any]:
    """One to three changes of types, bounds, lengths and keys of a scenario mapping."""
    for _ in range(draw(st.integers(1, 3))):
        paths = leaves(data)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        op = draw(st.sampled_from(["value", "scale", "delete", "unknown", "repeat", "grow"]))
        old = get(data, path)
        if op == "value":
            put(
                data,
                path,
                draw(st.one_of(st.sampled_from(NASTY), st.floats(), st.text(max_size=8))),
            )
        elif op == "scale" and isinstance(old, int | float) and not isinstance(old, bool):
            factor = draw(st.sampled_from([0, -1, 1e-300, 1e-9, 0.5, 1.5, 10, 1e9, 1e300]))
            put(data, path, old * factor)
        elif op == "delete":
            put(data, path, None, delete=True)
        elif op == "unknown" and isinstance(old, dict):
            old[draw(st.sampled_from(["spede", "Speed", "count ", "", "sweep", "x.y"]))] = 1
        elif op == "repeat" and isinstance(old, list) and old:
            put(data, path, [*old, old[0]])  # a duplicate in a list (a grid, policies)
        elif op == "grow" and isinstance(old, list):
            put(data, path, old * draw(st.sampled_from([0, 2, 50])))
    return data


def dump(data: dict[str, Any], suffix: str) -> str:
    try:
        return tomli_w.dumps(data) if suffix == ".toml" else yaml.safe_dump(data)
    except (TypeError, ValueError):  # no TOML for None or a mixed list: write YAML text
        return yaml.safe_dump(data)


def mutate_text(draw: Any, text: str) -> bytes:
    """Text-level mutations: a nasty line, truncation, a flipped byte, another encoding."""
    op = draw(st.sampled_from(["line", "line", "truncate", "byte", "encoding", "none"]))
    if op == "line":
        lines = text.splitlines()
        at = draw(st.integers(0, len(lines)))
        extra = draw(st.sampled_from([*NASTY_LINES, *(lines[at - 1 : at] or [""])]))
        text = "\n".join([*lines[:at], extra, *lines[at:]]) + "\n"
    elif op == "truncate":
        text = text[: draw(st.integers(0, len(text)))]
    data = text.encode("utf-8")
    if op == "byte" and data:
        at = draw(st.integers(0, len(data) - 1))
        data = data[:at] + bytes([draw(st.integers(0, 255))]) + data[at + 1 :]
    elif op == "encoding":
        codec = draw(st.sampled_from(["utf-8-sig", "utf-16", "latin-1", "cp1252"]))
        data = (text + "# caf\u00e9\n").encode(codec, errors="replace")
    return data


def mutate_csv(draw: Any, text: str) -> bytes:
    """Row, cell and header mutations of a CSV (a trace or measured targets)."""
    rows = [r.split(",") for r in text.splitlines()]
    body = [i for i, r in enumerate(rows) if r and not r[0].startswith("#")]
    header = body[0]
    for _ in range(draw(st.integers(1, 3))):
        op = draw(
            st.sampled_from(["cell", "cell", "header", "swap", "dup", "drop", "wide", "long"])
        )
        i = draw(st.sampled_from(body))
        if op == "cell":
            j = draw(st.integers(0, len(rows[i]) - 1))
            rows[i][j] = draw(st.one_of(st.sampled_from(CELLS), st.text(max_size=6)))
        elif op == "header":
            j = draw(st.integers(0, len(rows[header]) - 1))
            rows[header][j] = draw(st.sampled_from(HEADERS))
        elif op == "swap" and len(body) > 2:
            a, b = body[1], body[-1]
            rows[a], rows[b] = rows[b], rows[a]
        elif op == "dup":
            rows.insert(i, list(rows[i]))
        elif op == "drop":
            rows[i] = rows[i][:-1]
        elif op == "wide":
            rows[i] = [*rows[i], "1"]
        elif op == "long":
            rows += [list(rows[body[-1]]) for _ in range(draw(st.sampled_from([10, 3000])))]
    return mutate_text(draw, "\n".join(",".join(r) for r in rows) + "\n")


def make_kind(root: Path, name: str, kind: str) -> None:
    """Replace the input ``name`` by a file of another kind."""
    path = root / name
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        (path / "x").mkdir(parents=True)
    elif kind == "zero":
        os.symlink("/dev/zero", path)
    elif kind == "dangling":
        os.symlink(root / "gone", path)
    elif kind == "empty":
        path.write_bytes(b"")


@st.composite
def cases(draw: Any) -> tuple[list[str], dict[str, bytes], list[tuple[str, str]]]:
    """A command line, the corpus files as mutated, and the file kinds to make."""
    args = list(draw(st.sampled_from(COMMANDS)))
    files = {name: (CORPUS / name).read_bytes() for name in INPUTS}
    kinds: list[tuple[str, str]] = []
    used = [n for n in INPUTS if n in args] + (["trace.csv"] if "replay.yaml" in args else [])
    for target in draw(
        st.lists(st.sampled_from(["file", "csv", "kind", "args"]), min_size=1, max_size=3)
    ):
        name = draw(st.sampled_from(used or list(INPUTS)))
        if target == "file" and name.endswith((".toml", ".yaml")):
            seed = (CORPUS / name).read_text(encoding="utf-8")  # the seed, not a mutant
            data = (tomllib.loads if name.endswith(".toml") else yaml.safe_load)(seed)
            suffix = Path(name).suffix
            text = dump(mutate_mapping(draw, data), suffix)
            files[name] = mutate_text(draw, text) if draw(st.booleans()) else text.encode()
        elif target in ("file", "csv") and name.endswith(".csv"):
            files[name] = mutate_csv(draw, (CORPUS / name).read_text(encoding="utf-8"))
        elif target == "kind":
            kinds.append(
                (name, draw(st.sampled_from(["fifo", "folder", "zero", "dangling", "empty"])))
            )
        elif target == "args":
            args = mutate_args(draw, args)
    return args, files, kinds


def mutate_args(draw: Any, args: list[str]) -> list[str]:
    op = draw(st.sampled_from(["value", "drop", "extra", "extra", "repeat"]))
    options = [i for i, a in enumerate(args) if a.startswith("-") and i + 1 < len(args)]
    if op == "value" and options:
        i = draw(st.sampled_from(options))
        if not args[i + 1].startswith("-"):
            args[i + 1] = draw(st.sampled_from(NASTY_TEXT))
    elif op == "drop" and len(args) > 2:
        i = draw(st.integers(1, len(args) - 1))
        del args[i]
    elif op == "repeat" and options:
        i = draw(st.sampled_from(options))
        args += args[i : i + 2]
    else:
        args += draw(st.sampled_from(EXTRA_OPTIONS))
    return args


# --- checking the contract ---------------------------------------------------------------------


def snapshot(root: Path) -> dict[str, tuple[str, int]]:
    """Every entry under ``root``: a regular file's hash and mtime, any other entry's mode."""
    out: dict[str, tuple[str, int]] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st_ = p.lstat()
            key = str(p.relative_to(root))
            if p.is_symlink() or not p.is_file():
                out[key] = ("not a regular file", st_.st_mode)
            else:
                out[key] = (hashlib.sha256(p.read_bytes()).hexdigest(), st_.st_mtime_ns)
    return out


def outputs(args: list[str]) -> list[str]:
    """The paths the command line names as outputs (relative to the case's folder)."""
    return [
        os.path.normpath(args[i + 1])
        for i, a in enumerate(args[:-1])
        if a in OUTPUT_OPTIONS and args[0] not in ("validate",)
    ]


def inputs(args: list[str]) -> set[str]:
    """The corpus files the command line reads: its scenario, that one's trace, targets."""
    out = {args[1]} if len(args) > 1 else set()
    for i, a in enumerate(args[:-1]):
        if a in ("--targets", "-t"):
            out.add(args[i + 1])
        if a == "--set" and args[i + 1].startswith("feeder.trace="):
            out.add(args[i + 1].partition("=")[2])
    if "replay.yaml" in out:
        out.add("trace.csv")
    return {os.path.normpath(x) for x in out}


def allowed(path: str, outs: list[str]) -> bool:
    return any(path == o or path.startswith(o.rstrip("/") + "/") or o == "." for o in outs) or any(
        Path(o).parent.as_posix() != "." and path in {p.as_posix() for p in Path(o).parents}
        for o in outs
    )


def check_sane(args: list[str], stdout: str) -> None:
    if "--json" not in args or args[0] not in ("run", "calibrate"):
        return
    out = json.loads(stdout)
    g = out.get("gripping_rate")
    assert g is None or 0.0 <= g <= 100.0, g
    e = out.get("efficiency")
    assert e is None or 0.0 <= e <= 1.0 + 1e-9, e


@contextmanager
def small_limits() -> Iterator[None]:
    """Lower work limits: a mutation asking for a long run is refused, not run."""
    with (
        mock.patch("pnp_twin.twin.budget.MAX_PARTS", 5_000),
        mock.patch("pnp_twin.twin.budget.MAX_RUNS", 40),
    ):
        yield


@contextmanager
def outside_guard(args: list[str]) -> Iterator[None]:
    """With an output outside the case's folder (``--out /``, ``--out ..``), a study that
    would open it fails the case instead: a regression must not write into ``/``."""
    outside = [o for o in outputs(args) if os.path.isabs(o) or o.startswith("..")]
    if not outside:
        yield
        return
    boom = AssertionError(f"a study was opened outside the case's folder: {outside}")
    with (
        mock.patch("pnp_twin.studies.runner.open_session", side_effect=boom),
        mock.patch("pnp_twin.studies.lock.StudyLock", side_effect=boom),
    ):
        yield


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    derandomize=os.environ.get("PNP_FUZZ_RANDOM") != "1",
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(cases())
def test_every_input_is_answered_by_the_contract(
    case: tuple[list[str], dict[str, bytes], list[tuple[str, str]]],
) -> None:
    args, files, kinds = case
    with tempfile.TemporaryDirectory(prefix="pnp-fuzz-") as tmp:
        root = Path(tmp)
        for name, data in files.items():
            (root / name).write_bytes(data)
        (root / "filled").mkdir()
        (root / "filled" / "notes.txt").write_text("not a study", encoding="utf-8")
        for name, kind in kinds:
            make_kind(root, name, kind)
        before = snapshot(root)
        cwd = os.getcwd()
        os.chdir(root)
        try:
            t0 = time.perf_counter()
            with small_limits(), outside_guard(args), alarm(int(2 * LIMIT)):
                result = CliRunner().invoke(app, args)
            seconds = time.perf_counter() - t0
        finally:
            os.chdir(cwd)
        where = f"{shlex.join(args)} (files {sorted(n for n in files)}, kinds {kinds})"
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            raise AssertionError(f"{where}: {result.exception!r}") from result.exception
        stderr = result.stderr
        assert "Traceback" not in stderr, f"{where}: {stderr}"
        assert result.exit_code in (0, 2), f"{where}: exit {result.exit_code}: {stderr}"
        assert seconds < LIMIT, f"{where}: {seconds:.1f} s"
        event(f"{args[0]}: exit {result.exit_code}")  # --hypothesis-show-statistics
        after = snapshot(root)
        if result.exit_code == 2:
            lines = stderr.splitlines()
            assert result.stdout == "", f"{where}: {result.stdout}"
            assert len(lines) == 1 and lines[0].startswith("error: "), f"{where}: {stderr}"
            assert len(lines[0]) <= MAX_LINE, f"{where}: {lines[0]}"
            assert after == before, f"{where}: a refusal wrote {set(after) ^ set(before)}"
        else:
            outs = outputs(args)
            changed = {k for k in before if after.get(k) != before[k]}
            assert not changed & inputs(args), f"{where}: changed inputs {changed}"
            assert not {k for k in changed if not allowed(k, outs)}, f"{where}: changed {changed}"
            stray = {k for k in set(after) - set(before) if not allowed(k, outs)}
            assert not stray, f"{where}: wrote outside its outputs {stray}"
            check_sane(args, result.stdout)
        shutil.rmtree(root, ignore_errors=True)


def test_the_corpus_is_valid_and_every_seed_command_succeeds(tmp_path: Path) -> None:
    """The seeds themselves pass (so every mutation starts from a working input)."""
    for name in INPUTS:
        shutil.copy(CORPUS / name, tmp_path / name)
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for args in COMMANDS:
            result = CliRunner().invoke(app, args)
            assert result.exit_code == 0, (args, result.stderr)
    finally:
        os.chdir(cwd)


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero", "dangling", "empty"])
def test_every_file_kind_of_every_input_is_refused(kind: str, tmp_path: Path) -> None:
    """The file kinds, exhaustively: each input of each seed command, made a FIFO, a folder,
    a link to /dev/zero, a dangling link or an empty file, is refused in one line."""
    for c, args in enumerate(COMMANDS):
        for name in sorted(inputs(args)):
            root = tmp_path / f"{c}-{name}"
            root.mkdir()
            for other in INPUTS:
                shutil.copy(CORPUS / other, root / other)
            make_kind(root, name, kind)
            before = snapshot(root)
            cwd = os.getcwd()
            os.chdir(root)
            try:
                with alarm(int(LIMIT)):
                    result = CliRunner().invoke(app, args)
            finally:
                os.chdir(cwd)
            assert result.exit_code == 2, (args, kind, result.output)
            assert len(result.stderr.splitlines()) == 1, result.stderr
            assert name in result.stderr, result.stderr
            assert snapshot(root) == before
