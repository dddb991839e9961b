"""Imports run one way (the import-linter contracts in pyproject.toml), and the checker can
fail: a planted upward import in a copy of the tree breaks the contract."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("twin", "policies", "reports", "pnp_twin")


def lint_imports(root: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).with_name("lint-imports")
    return subprocess.run(
        [str(exe), "--no-cache"],
        cwd=root,
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(root), "PATH": str(exe.parent)},
    )


def copy_tree(dest: Path) -> Path:
    for name in PACKAGES:
        shutil.copytree(ROOT / name, dest / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", dest / "pyproject.toml")
    return dest


def test_the_repository_keeps_its_layers() -> None:
    out = lint_imports(ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 broken" in out.stdout


def test_a_core_module_importing_a_policy_breaks_the_contract(tmp_path: Path) -> None:
    tree = copy_tree(tmp_path)
    belt = tree / "twin" / "belt.py"
    belt.write_text(belt.read_text() + "\nimport policies.rules  # noqa\n")
    out = lint_imports(tree)
    assert out.returncode != 0
    assert "twin.belt -> policies.rules" in out.stdout


def test_a_policy_importing_the_cli_breaks_the_contract(tmp_path: Path) -> None:
    tree = copy_tree(tmp_path)
    rules = tree / "policies" / "rules.py"
    rules.write_text(rules.read_text() + "\nimport pnp_twin.cli.app  # noqa\n")
    out = lint_imports(tree)
    assert out.returncode != 0
    assert "policies.rules -> pnp_twin.cli.app" in out.stdout


def test_importing_the_core_loads_nothing_above_it() -> None:
    code = (
        "import sys, twin, twin.line, twin.camera, twin.run, twin.kpis, twin.stats\n"
        "up = ('policies', 'reports', 'pnp_twin', 'torch', 'gymnasium', 'plotly', 'scipy')\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in up))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]", out.stdout
