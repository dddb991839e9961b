"""Which command's folder a folder is: the record every output folder carries.

A command that claims a folder (a study, a calibration, a design, a training run ...)
writes ``DIR/.pnp-twin.json`` (``{"kind": "design", "format": 1}``) before anything else,
and a folder is only ever resumed or rewritten by the same kind of command: a ``headroom``
into a ``design`` folder is refused, not allowed to overwrite its report. Folders written
before the record existed are recognised by the file that only their kind writes.
"""

from __future__ import annotations

import json
from pathlib import Path

from pnp_twin.twin.output import write_json

KIND_FILE = ".pnp-twin.json"
FORMAT = 1

LEGACY = (  # a folder without the record: the file that only its kind writes
    ("design.json", "design"),
    ("capacity.json", "capacity"),
    ("calibration.json", "calibrate"),
    ("headroom.json", "headroom"),
    ("tune.json", "tune"),
)


def folder_kind(folder: str | Path) -> str | None:
    """The kind of command that wrote ``folder``: its record, else what its files say
    (``study.json``/``meta.json`` name sweep, size and mix); None when nothing says."""
    p = Path(folder)
    for name in (KIND_FILE, "study.json", "meta.json"):
        kind = _kind_in(p / name)
        if kind is not None:
            return kind
    return next((kind for name, kind in LEGACY if (p / name).is_file()), None)


def _kind_in(path: Path) -> str | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    kind = data.get("kind") if isinstance(data, dict) else None
    return kind if isinstance(kind, str) and kind else None


def write_kind(folder: str | Path, kind: str) -> None:
    """Record that ``folder`` belongs to a ``kind`` command (written atomically)."""
    write_json({"kind": kind, "format": FORMAT}, Path(folder) / KIND_FILE)
