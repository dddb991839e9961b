"""Running from a checkout: the card's top-level folders as this package's subpackages.

pyproject's ``[tool.setuptools.package-dir]`` maps ``twin/``, ``policies/``, ``reports/``,
``scenarios/`` and ``models/`` to ``pnp_twin.twin`` ... (no symbolic links: git on Windows
checks those out as text files). A wheel holds them inside ``pnp_twin/``, and an editable
install maps them; this finder makes the same mapping hold whenever ``pnp_twin`` is imported
from a checkout (a checkout on ``PYTHONPATH``, another worktree), so each checkout always
imports its own folders, never another's.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

FOLDERS = ("twin", "policies", "reports", "scenarios", "models")
PACKAGE = Path(__file__).resolve().parent
ROOT = PACKAGE.parent


class CheckoutFolders(importlib.abc.MetaPathFinder):
    """Finds ``pnp_twin.<folder>`` in the checkout's top-level ``<folder>/``."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        top, _, name = fullname.partition(".")
        if top != PACKAGE.name or name not in FOLDERS:
            return None
        return importlib.machinery.PathFinder.find_spec(fullname, [str(ROOT)])


def install() -> None:
    """Put the finder first on ``sys.meta_path`` when this package sits in a checkout."""
    in_checkout = (ROOT / "pyproject.toml").is_file() and (ROOT / "twin" / "__init__.py").is_file()
    if in_checkout and not (PACKAGE / "twin").exists():
        if not any(isinstance(f, CheckoutFolders) for f in sys.meta_path):
            sys.meta_path.insert(0, CheckoutFolders())
