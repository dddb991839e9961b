"""The one door every command's outputs go out through.

Before anything is written, a command names what it reads (:func:`inputs_of`: the scenario
file, every trace of a trace folder and the folder itself, targets, cost and policy files,
models) and claims what it writes:

- an output file (:func:`check_output_file`): writable, not one of the inputs, not inside
  an input folder;
- an output folder (:func:`claim_folder`): new, empty, or a folder of the same kind of
  command to resume (see :mod:`pnp_twin.twin.folder_kind`); not holding an input and not
  inside one; then locked for the command's life, its kind recorded, and removed again
  when the command is refused before it wrote a result.

A new command that claims through here inherits every protection.
"""

from __future__ import annotations

import shlex
import sys
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from pnp_twin.twin.errors import clip
from pnp_twin.twin.folder_kind import KIND_FILE, folder_kind, write_kind
from pnp_twin.twin.loader import find_scenario
from pnp_twin.twin.output import (
    LOCK_NAMES,
    OutputError,
    check_not_inputs,
    check_out_folder,
    check_writable,
    removed_if_refused,
)
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import trace_files, trace_folders

Inputs = Mapping[str, str | Path | None]


def inputs_of(scenario: str | Path | None, sc: Scenario | None = None, **more: object) -> Inputs:
    """What a command reads: the scenario file, each trace it replays (and a trace folder
    itself), and ``more`` (label -> path; a ``py:FILE.py:...`` policy names its file)."""
    out: dict[str, str | Path | None] = {}
    if scenario is not None:
        out["scenario file"] = find_scenario(scenario)
    if sc is not None:
        for i, path in enumerate(trace_files(sc)):
            out[f"trace {i + 1}" if i else "trace"] = path
        for i, path in enumerate(trace_folders(sc)):
            out[f"trace folder {i + 1}" if i else "trace folder"] = path
    for label, value in more.items():
        for i, path in enumerate(_paths(value)):
            out[f"{label} {i + 1}" if i else label] = path
    return out


def _paths(value: object) -> list[Path]:
    """The files a value names: a path, or the file or folder a policy spec reads
    (``py:FILE.py:...``, ``hdqn:DIR``, ``sb3:FILE.zip[@RULES]``); a rule names none."""
    values = value if isinstance(value, list | tuple) else [value]
    out = []
    for v in values:
        if isinstance(v, Path):
            out.append(v)
        elif isinstance(v, str) and v.startswith("py:") and ".py:" in v:
            out.append(Path(v[3:].split(".py:", 1)[0] + ".py"))
        elif isinstance(v, str) and v.startswith(("hdqn:", "sb3:")):
            target = v.partition(":")[2].partition("@")[0].strip()
            if target:
                out.append(Path(target))
    return out


def check_output_file(path: str | Path, option: str, inputs: Inputs) -> Path:
    """``path`` if a command may write it: writable, neither an input nor inside one."""
    p = check_writable(path, option)
    check_not_inputs(p, inputs, option)
    return p


def check_folder(
    out: str | Path,
    kind: str,
    inputs: Inputs,
    option: str = "--out",
    legacy: Iterable[str] = (),
) -> Path:
    """Check an output folder before anything is written: new, empty, or a ``kind`` folder
    (one of ours of another kind is refused, naming it), holding no input, inside none.
    ``legacy``: entries that mark a ``kind`` folder written before kinds were recorded."""
    p = Path(out)
    ours = {KIND_FILE, *LOCK_NAMES, *legacy}
    found = folder_kind(p) if p.is_dir() else None
    if found is not None and found != kind:
        raise OutputError(
            f"{option} {clip(str(p))}: is a folder of `pnp-twin {found}`; `{kind}` resumes only "
            f"its own folders, so writing there would mix or overwrite the {found} results; "
            "choose another folder"
        )
    if found == kind:
        ours |= {e.name for e in p.iterdir()}  # ours to resume: whatever it holds
    elif p.is_dir() and _legacy_evals(p):
        ours.add("evals")  # a killed design/capacity/calibration of an earlier version
    return check_out_folder(p, inputs, ours, option)


def _legacy_evals(p: Path) -> bool:
    """A folder of an earlier version holding only a killed study's per-run journal."""
    names = {e.name for e in p.iterdir()}
    return "evals" in names and names <= {"evals", *LOCK_NAMES}


@contextmanager
def claim_folder(
    out: str | Path,
    kind: str,
    inputs: Inputs,
    option: str = "--out",
    lock: bool = True,
    legacy: Iterable[str] = (),
) -> Iterator[str]:
    """Check ``out`` (:func:`check_folder`), then hold it for the block: locked (unless
    ``lock`` is False: the study journal or the trainer keeps its own), its kind recorded,
    and removed again if the block fails before writing a result. Yields the command line."""
    from pnp_twin.studies.lock import StudyLock  # the study layer: only when a folder is held

    folder = check_folder(out, kind, inputs, option, legacy)
    command = shlex.join(["pnp-twin", *sys.argv[1:]])
    with removed_if_refused(folder):
        held = StudyLock(folder) if lock else None
        if held is not None:
            held.acquire(command)
        try:
            if not (folder / KIND_FILE).is_file():
                write_kind(folder, kind)
            yield command
        finally:
            if held is not None:
                held.release()
