"""A fuzzer that covers every command of the app by construction (hypothesis).

The commands and their options are read from the application itself (Typer's registered
commands and groups, each callback's signature), not from a list kept by hand: every path
option gets the bad-path classes (missing, a folder, a FIFO, a link to /dev/zero, a dangling
link, an empty file, bytes that are not text), every number the bad-number classes (NaN,
infinities, negatives, 0, 1e308, digits that are not ASCII ...), every output the folder
classes (``/``, the case folder, an input file, a folder of other files, a folder of another
command, inside the trace folder), every text option odd text. A command without a seed
command line below fails :func:`test_every_command_has_a_seed`, so a new command is fuzzed
the day it is added; so does a path option that is neither an input nor an output.

Each case runs in-process in an empty folder holding the corpus and must meet the contract of
``test_fuzz_cli``: exit 0 or 2, never a traceback; on exit 2 exactly one ``error:`` line and
nothing written; an answer within the time limit.
"""

from __future__ import annotations

import inspect
import json
import os
import shlex
import shutil
import tempfile
import time
import typing
from enum import Enum
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from typer.models import ArgumentInfo, OptionInfo
from typer.testing import CliRunner

from pnp_twin.cli import app, load_commands
from tests.cli.test_bad_inputs import MAX_LINE, alarm
from tests.fuzz.test_fuzz_cli import CORPUS, INPUTS, make_kind, small_limits, snapshot

EXAMPLES = int(os.environ.get("PNP_FUZZ_COMMAND_EXAMPLES", "60"))
LIMIT = 30.0  # s per case on a loaded 2-core machine (train's seed takes about 12 s)
QUICK = ["--workers", "1"]

SEEDS: dict[str, list[str]] = {  # one small working command line per command
    "run": ["run", "line.toml", "--engine", "simpy", "--json", "--events", "parts.csv"],
    "validate": ["validate", "line.toml"],
    "schema": ["schema", "--out", "schema.json"],
    "list": ["list"],
    "sweep": ["sweep", "study.toml", "--out", "st", *QUICK, "--engine", "simpy", "--no-report"],
    "size": ["size", "study.toml", "--out", "sz", *QUICK, "--no-report", "--set",
             "sweep.grid={robots.count: [1, 2]}"],
    "mix": ["mix", "study.toml", "--out", "mx", *QUICK, "--no-report", "--rules", "SD,FIFO",
            "--budget", "2"],
    "report": ["report", "done", "--out", "again.html"],
    "export": ["export", "done", "--xlsx", "done.xlsx"],
    "train": ["train", "line.toml", "--out", "tr", "--steps", "30", "--learning-starts", "10",
              "--eval-every", "30", "--eval-seeds", "1", "--eval-duration", "3"],
    "evaluate": ["evaluate", "line.toml", "--policy", "lookahead:K=2,H=0.5", "--seeds", "2",
                 "--duration", "5", "--mix", "SD"],
    "calibrate": ["calibrate", "line.toml", "--targets", "targets.csv", "--out", "cal", "--fit",
                  "robots.pick_time=0.05:0.2", "-r", "2", "--max-evals", "2", "--profile", "0",
                  "--policy", "SD",
                  "--pairs", "0", *QUICK, "--no-report"],
    "capacity": ["capacity", "line.toml", "--target", "80", "--out", "cap", "-r", "2", *QUICK,
                 "--no-report"],
    "design": ["design", "line.toml", "--target", "80", "--vary", "robots.arm_speed=2,3",
               "--out", "des", "-r", "2", "--max-replications", "2", *QUICK, "--no-report"],
    "headroom": ["headroom", "line.toml", "--out", "hr", "--seeds", "2", "--duration", "5",
                 "--lookahead", "lookahead:K=2,H=0.5", "--mix", "SD", "-p", "py:mine.py:P"],
    "tune": ["tune", "line.toml", "--out", "tu", "--trials", "2", "--tuning-seeds", "2",
             "--seeds", "2", "--duration", "5"],
    "task list": ["task", "list"],
    "compare": ["compare", "line.toml", "-p", "SD", "-p", "py:mine.py:P", "--report", "c.html"],
    "task score": ["task", "score", "baseline", "-p", "SD", "--seeds", "2", "--duration", "5"],
}  # fmt: skip

INPUT_OPTIONS = {"scenario", "targets", "costs", "study_dir", "task", "policy", "mix", "baseline"}
OUTPUT_OPTIONS = {"out", "events", "spans", "report", "xlsx", "gif", "write_scenario"}
OUTPUT_FLAGS = {"o", *(n.replace("_", "-") for n in OUTPUT_OPTIONS)}
POLICY = "class P:\n    def reset(self, robots, rng): pass\n    def choose(self, d): return 0\n"
BAD_HEAD = "class P:\n    def reset(self, robots, rng): pass\n"
BAD_POLICIES = [  # each answer or failure of a user's policy: the body of its choose()
    "    def choose(self, d): return float('nan')\n",
    "    def choose(self, d): return 10**9\n",
    "    def choose(self, d): return '0'\n",
    "    def choose(self, d): raise SystemExit(3)\n",
    "    def choose(self, d): return 1 / 0\n",
    "    def choose(self, d):\n        import time; time.sleep(60)\n",
]

BAD_NUMBERS = ["nan", "inf", "-inf", "-1", "0", "1e308", "x", "99999999999999999999",
               "1e-300", "\u00b2", "", " 3"]  # fmt: skip
BAD_TEXT = ["", "x" * 300, "NOPE", "py:nothere.py:F", "py:mine.py:Nope", "hdqn:nothere",
            "\u00e9", "lookahead:K=\u00b2", "SD,SD,SD", "sb3:nothere.zip",
            "py:bad.py:P"]  # fmt: skip
BAD_PATHS = ["nothere.toml", ".", "fifo", "zero", "dangling", "empty", "binary.toml"]
BAD_OUTPUTS = ["/", ".", "line.toml", "trace.csv", "filled", "trace.csv/x", "done", "other",
               "shifts", "shifts/x.csv"]  # fmt: skip


def commands() -> dict[str, list[tuple[str, str, Any]]]:
    """Every command (``task score`` for a group's) -> its options: (flag, name, type)."""
    load_commands()
    found: dict[str, Any] = {}
    for info in app.registered_commands:
        found[info.name or info.callback.__name__] = info.callback
    for group in app.registered_groups:
        for info in group.typer_instance.registered_commands:
            found[f"{group.name} {info.name}"] = info.callback
    return {name: _options(callback) for name, callback in found.items()}


def _options(callback: Any) -> list[tuple[str, str, Any]]:
    out = []
    for name, param in inspect.signature(callback).parameters.items():
        annotation = param.annotation
        if isinstance(annotation, str):
            annotation = typing.get_type_hints(callback, include_extras=True)[name]
        base, *extras = typing.get_args(annotation) or (annotation,)
        info = next((e for e in extras if isinstance(e, OptionInfo | ArgumentInfo)), None)
        if isinstance(info, ArgumentInfo) or info is None:
            out.append(("", name, _bare(base)))
            continue
        decls = [d for d in (info.param_decls or ()) if d.startswith("--")]
        flag = decls[0] if decls else "--" + name.replace("_", "-")
        out.append((flag, name, _bare(base)))
    return out


def _bare(t: Any) -> Any:
    """``int | None`` -> int; ``list[str] | None`` -> str; an Enum stays itself."""
    args = [a for a in typing.get_args(t) if a is not type(None)]
    if typing.get_origin(t) in (list, tuple):
        return _bare(args[0])
    if args and typing.get_origin(t) is not None:
        return _bare(args[0])
    return t


COMMANDS = commands()


def test_every_command_has_a_seed() -> None:
    """A new command must bring a seed command line here, so it is fuzzed from day one."""
    missing = sorted(set(COMMANDS) - set(SEEDS))
    assert not missing, f"no seed command line for {missing}: add one to SEEDS"
    assert len(COMMANDS) >= 18


def test_every_path_option_is_an_input_or_an_output() -> None:
    """Each Path-typed option is fuzzed with the input or the output classes: a new one must
    say which (so neither is skipped by accident)."""
    paths = {name for opts in COMMANDS.values() for _, name, t in opts if t is Path}
    assert paths <= INPUT_OPTIONS | OUTPUT_OPTIONS, paths - (INPUT_OPTIONS | OUTPUT_OPTIONS)


def bad_values(name: str, t: Any) -> list[str]:
    """The bad classes for an option of type ``t``."""
    if name in OUTPUT_OPTIONS:
        return BAD_OUTPUTS
    if t is Path or name in INPUT_OPTIONS:
        return BAD_PATHS + (BAD_TEXT if name in ("policy", "mix", "task") else [])
    if t is bool:
        return []
    if t in (int, float):
        return BAD_NUMBERS
    if isinstance(t, type) and issubclass(t, Enum):
        return ["nope", "", "FAST"]
    return BAD_TEXT + BAD_NUMBERS[:4]


@st.composite
def cases(draw: Any) -> tuple[list[str], int]:
    """A seed command line with one option (or the argument) given a bad value, and which
    of :data:`BAD_POLICIES` ``bad.py`` holds."""
    name = draw(st.sampled_from(sorted(COMMANDS)))
    bad = draw(st.integers(0, len(BAD_POLICIES) - 1))
    args = list(SEEDS[name])
    options = [(f, n, t) for f, n, t in COMMANDS[name] if bad_values(n, t)]
    if not options:
        return args, bad
    flag, opt, t = draw(st.sampled_from(options))
    value = draw(st.sampled_from(bad_values(opt, t)))
    words = len(name.split())
    if not flag:  # the positional argument
        if len(args) > words:
            args[words] = value
    elif flag in args:
        args[args.index(flag) + 1] = value
    else:
        args += [flag, value]
    return args, bad


def make_case_folder(root: Path, done: Path) -> None:
    """The corpus, a finished study (``done``), a folder of other files, one of another
    command, a trace folder, a user policy (good and bad) and the odd kinds of file."""
    for name in INPUTS:
        shutil.copy(CORPUS / name, root / name)
    shutil.copytree(done, root / "done")
    (root / "filled").mkdir()
    (root / "filled" / "notes.txt").write_text("not a study", encoding="utf-8")
    (root / "other").mkdir()
    (root / "other" / ".pnp-twin.json").write_text('{"kind": "zzz", "format": 1}')
    (root / "shifts").mkdir()
    shutil.copy(CORPUS / "trace.csv", root / "shifts" / "a.csv")
    (root / "mine.py").write_text(POLICY, encoding="utf-8")
    (root / "binary.toml").write_bytes(bytes(range(256)))
    for kind in ("fifo", "zero", "dangling", "empty"):
        make_kind(root, kind, kind)


DONE: list[Path] = []


def done_study() -> Path:
    """A finished tiny sweep, made once per session (``report`` and ``export`` read it)."""
    if not DONE:
        folder = Path(tempfile.mkdtemp(prefix="pnp-fuzz-done-"))
        for name in INPUTS:
            shutil.copy(CORPUS / name, folder / name)
        cwd = os.getcwd()
        os.chdir(folder)
        try:
            result = CliRunner().invoke(app, [*SEEDS["sweep"][:2], "--out", "done", *QUICK])
        finally:
            os.chdir(cwd)
        assert result.exit_code == 0, result.stderr
        DONE.append(folder / "done")
    return DONE[0]


def run_case(args: list[str], root: Path) -> tuple[Any, float]:
    cwd = os.getcwd()
    os.chdir(root)
    try:
        t0 = time.perf_counter()
        with small_limits(), alarm(int(2 * LIMIT)):
            result = CliRunner().invoke(app, args, env={"PNP_TWIN_DECISION_TIMEOUT": "2"})
        return result, time.perf_counter() - t0
    finally:
        os.chdir(cwd)


def check_contract(args: list[str], root: Path, before: dict[str, Any]) -> None:
    result, seconds = run_case(args, root)
    where = shlex.join(args)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"{where}: {result.exception!r}") from result.exception
    assert "Traceback" not in result.stderr, f"{where}: {result.stderr}"
    assert result.exit_code in (0, 2), f"{where}: exit {result.exit_code}: {result.stderr}"
    assert seconds < LIMIT, f"{where}: {seconds:.1f} s"
    event(f"{args[0]}: exit {result.exit_code}")
    if result.exit_code == 2:
        lines = result.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), f"{where}: {result.stderr}"
        assert len(lines[0]) <= MAX_LINE, f"{where}: {lines[0]}"
        after = snapshot(root)
        assert after == before, f"{where}: a refusal wrote {set(after) ^ set(before)}"
    else:
        changed = {k for k, v in before.items() if snapshot(root).get(k) != v}
        assert not changed & read_by(args), f"{where}: changed inputs {changed}"


def read_by(args: list[str]) -> set[str]:
    """The case folder's files the command line reads (every file it names, but as an
    output), with the traces a scenario replays and a policy's file."""
    outputs = {args[i + 1] for i, a in enumerate(args[:-1]) if a.lstrip("-") in OUTPUT_FLAGS}
    named = {a for a in args if a not in outputs}
    files = {n for n in (*INPUTS, "mine.py", "bad.py") if any(n in a for a in named)}
    return files | ({"trace.csv"} if "replay.yaml" in files else set())


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    derandomize=os.environ.get("PNP_FUZZ_RANDOM") != "1",
    suppress_health_check=[HealthCheck.too_slow],
)
@given(cases())
def test_every_command_answers_every_bad_value_by_the_contract(case: tuple[list[str], int]) -> None:
    args, bad = case
    done = done_study()
    with tempfile.TemporaryDirectory(prefix="pnp-fuzz-cmd-") as tmp:
        root = Path(tmp)
        make_case_folder(root, done)
        (root / "bad.py").write_text(BAD_HEAD + BAD_POLICIES[bad], encoding="utf-8")
        check_contract(args, root, snapshot(root))


def test_every_seed_command_line_succeeds(tmp_path: Path) -> None:
    """The seeds themselves pass, each run of them writing only where it says."""
    make_case_folder(tmp_path, done_study())
    for name, args in SEEDS.items():
        result, _ = run_case(args, tmp_path)
        assert result.exit_code == 0, (name, result.stderr[-500:])
    assert json.loads((tmp_path / "schema.json").read_text())["title"]


def test_a_user_policy_that_fails_in_any_way_is_one_line(tmp_path: Path) -> None:
    """Each bad answer or failure of a py: policy, in a study's worker processes too, is one
    line naming the policy, exit 2, and the study folder it would have made is not left."""
    make_case_folder(tmp_path, done_study())
    for body in BAD_POLICIES:
        (tmp_path / "bad.py").write_text(BAD_HEAD + body, encoding="utf-8")
        for args in (
            ["run", "line.toml", "-p", "py:bad.py:P", "--json"],
            ["sweep", "study.toml", "--out", "sw", "-p", "py:bad.py:P", "--workers", "2"],
        ):
            result, _ = run_case(args, tmp_path)
            assert result.exit_code == 2, (args, body, result.stderr)
            assert result.stderr.count("\n") == 1 and "policy py:bad.py:P" in result.stderr
            assert not (tmp_path / "sw").exists(), (body, result.stderr)
