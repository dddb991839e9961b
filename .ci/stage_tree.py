"""Lay the package out as the wheel installs it, in ``build/stage``, for the tools that find
modules on the file system (mypy, import-linter).

The checkout keeps the card's top-level folders (``twin/``, ``policies/``, ``reports/``,
``scenarios/``, ``models/``) and maps them into the one package ``pnp_twin`` through
``[tool.setuptools] package-dir`` (no symbolic links: git on Windows checks those out as
text files). Python imports follow that mapping; mypy and import-linter read folders, so
they run on this stage: every ``.py`` file hard-linked (copied where links fail) into
``build/stage/<package path>``.

    python .ci/stage_tree.py [DEST]
"""

from __future__ import annotations

import os
import shutil
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def source_of(package: str, mapping: dict[str, str]) -> Path:
    """The checkout folder of ``package``: its longest mapped prefix's folder + the rest."""
    parts = package.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        if prefix in mapping:
            return ROOT / mapping[prefix] / Path(*parts[n:])
    return ROOT / Path(*parts)


def stage(dest: Path) -> int:
    """Build the stage in ``dest``; the number of files placed."""
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    shutil.rmtree(dest, ignore_errors=True)
    placed = 0
    for package in setuptools["packages"]:
        target = dest / Path(*package.split("."))
        target.mkdir(parents=True, exist_ok=True)
        for f in sorted(source_of(package, setuptools["package-dir"]).glob("*.py*")):
            if f.suffix not in (".py", ".pyi") or not f.is_file():
                continue
            try:
                os.link(f, target / f.name)
            except OSError:
                shutil.copy2(f, target / f.name)
            placed += 1
    return placed


if __name__ == "__main__":
    where = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "build" / "stage"
    print(f"staged {stage(where)} files in {where}")
