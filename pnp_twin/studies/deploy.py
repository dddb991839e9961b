"""The chosen line as a scenario file (``--write-scenario FILE`` of ``design``, ``size`` and
``tune``): the line to deploy, which ``pnp-twin run FILE`` reproduces.

The file holds the resolved scenario of the choice (every field, so it does not depend on
the defaults of a later version), its rule as ``policy``, and as ``seed`` the seed of the
study's first replication, so ``pnp-twin run FILE`` gives that replication's KPIs exactly;
the comment block at its head says what was asked, the answer and every replication's seed.
A trace the line replays is named by its absolute path (the file may move).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.errors import clip
from pnp_twin.twin.inputs import file_kind
from pnp_twin.twin.output import check_not_inputs, dumps_toml, write_text
from pnp_twin.twin.trace import trace_paths

MARK = "# pnp-twin: the line chosen by"  # first line of every file written here


def check_scenario_out(path: Path, inputs: Mapping[str, str | Path | None], option: str) -> None:
    """Refuse, before anything runs, a ``--write-scenario`` path that is not a new .toml file
    (or one written here before), lies in a missing folder, or is one of the inputs."""
    p = Path(path)
    if p.suffix.lower() != ".toml":
        raise StudyError(f"{option} {clip(str(p))}: give a file name ending in .toml")
    kind = file_kind(p)
    if kind is not None:
        raise StudyError(f"{option} {clip(str(p))}: is {kind}; give a new .toml file")
    if not p.parent.is_dir():
        raise StudyError(f"{option} {clip(str(p))}: folder '{p.parent}' does not exist")
    check_not_inputs(p, inputs, option)
    if p.exists():
        try:
            with open(p, encoding="utf-8", errors="replace") as f:
                first = f.readline()
        except OSError as e:
            raise StudyError(f"{option} {clip(str(p))}: cannot be read: {e.strerror}") from None
        if not first.startswith(MARK):
            raise StudyError(
                f"{option} {clip(str(p))}: exists and was not written by pnp-twin; give a new "
                "file (an earlier choice written by pnp-twin is replaced)"
            )


def scenario_file_text(
    scenario: Mapping[str, Any],
    policy: str,
    seeds: Sequence[int],
    command: str,
    about: Sequence[str],
    source_dir: str | None,
) -> str:
    """The scenario file of a choice: a comment block, then every field."""
    data = dict(scenario)
    data["policy"] = policy
    if seeds:
        data["seed"] = int(seeds[0])
    feeder = dict(data.get("feeder") or {})
    if feeder.get("trace"):
        files = [str(p.resolve()) for p in trace_paths(feeder["trace"], source_dir)]
        feeder["trace"] = files[0] if isinstance(feeder["trace"], str) else files
        data["feeder"] = feeder
    head = [f"{MARK.removeprefix('# ')} {command}", *about]
    if seeds:
        head.append(
            f"seed = replication 1's; the study's replications ran with seeds "
            f"{', '.join(str(s) for s in seeds)} (pnp-twin run FILE --seed S for another)"
        )
    return "".join(f"# {line}\n" for line in head) + dumps_toml(data)


def write_scenario_file(path: Path, text: str) -> Path:
    """Write the file atomically; returns its path."""
    return write_text(text, Path(path))
