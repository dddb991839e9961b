"""The simulation core never imports ``policies`` (front ends such as the CLI may)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CORE = [
    "scenario",
    "loader",
    "belt",
    "feeder",
    "robot",
    "bin",
    "gateway",
    "decision",
    "line",
    "records",
    "kpis",
    "run",
    "geometry",
    "errors",
    "__init__",
]


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every import in a file, at any depth (functions included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
        elif (  # importlib.import_module("policies...") / __import__("policies...")
            isinstance(node, ast.Call)
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
            and (
                (isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                or (isinstance(node.func, ast.Name) and node.func.id in ("__import__",))
            )
        ):
            out.append((node.lineno, node.args[0].value))
    return out


def is_policies(module: str) -> bool:
    return module == "policies" or module.startswith("policies.")


def test_the_parser_finds_policies_imports(tmp_path: Path) -> None:
    # the check must be able to fail: it does catch each form on a sample
    sample = tmp_path / "sample.py"
    sample.write_text(
        "import policies\nfrom policies.rules import RULES\nimport os, policies.base\n"
        "from policy_tools import x\n"
        "def f():\n    import importlib\n    return importlib.import_module('policies.x')\n",
        encoding="utf-8",
    )
    found = [m for _, m in imported_modules(sample) if is_policies(m)]
    assert found == ["policies", "policies.rules", "policies.base", "policies.x"]


@pytest.mark.parametrize("name", CORE)
def test_core_module_does_not_import_policies(name: str) -> None:
    path = ROOT / "twin" / f"{name}.py"
    assert path.is_file(), f"core module {path} is missing"
    bad = [(line, m) for line, m in imported_modules(path) if is_policies(m)]
    assert not bad, f"twin/{name}.py imports {bad}"


def test_importing_the_core_loads_no_policy_module() -> None:
    # transitively, too: a fresh interpreter imports every core module and looks
    modules = ", ".join(f"twin.{n}" for n in CORE if n != "__init__")
    code = (
        f"import sys, twin, {modules}\n"
        "bad = sorted(m for m in sys.modules if m == 'policies' or m.startswith('policies.'))\n"
        "print(bad)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]", out.stdout
