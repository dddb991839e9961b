"""Imports run one way (the import-linter contracts in pyproject.toml), and the checker can
fail: a planted upward import in a copy of the tree breaks the contract. Everything is
imported under the one package ``pnp_twin``: no source names a top-level ``twin``,
``policies``, ``reports``, ``scenarios`` or ``models``."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("twin", "policies", "reports", "scenarios", "models")  # mapped into pnp_twin
PACKAGES = (*FOLDERS, "pnp_twin")


def stage(root: Path, dest: Path) -> Path:
    """The package as installed (``.ci/stage_tree.py``), where import-linter can read it."""
    script = root / ".ci" / "stage_tree.py"
    subprocess.run([sys.executable, str(script), str(dest)], check=True, capture_output=True)
    return dest


def lint_imports(root: Path, tmp: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).with_name("lint-imports")
    staged = stage(root, tmp / "stage")
    return subprocess.run(
        [str(exe), "--no-cache", "--config", str(root / "pyproject.toml")],
        cwd=staged,
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(staged), "PATH": str(exe.parent)},
    )


def copy_tree(dest: Path) -> Path:
    for name in PACKAGES:
        ignore = shutil.ignore_patterns("__pycache__")
        shutil.copytree(ROOT / name, dest / name, ignore=ignore)
    shutil.copytree(ROOT / ".ci", dest / ".ci")
    shutil.copy(ROOT / "pyproject.toml", dest / "pyproject.toml")
    return dest


def test_the_repository_keeps_its_layers(tmp_path: Path) -> None:
    out = lint_imports(ROOT, tmp_path)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 broken" in out.stdout


def test_a_core_module_importing_a_policy_breaks_the_contract(tmp_path: Path) -> None:
    tree = copy_tree(tmp_path / "tree")
    belt = tree / "twin" / "belt.py"
    belt.write_text(belt.read_text() + "\nimport pnp_twin.policies.rules  # noqa\n")
    out = lint_imports(tree, tmp_path)
    assert out.returncode != 0
    assert "pnp_twin.twin.belt -> pnp_twin.policies.rules" in out.stdout


def test_a_policy_importing_the_cli_breaks_the_contract(tmp_path: Path) -> None:
    tree = copy_tree(tmp_path / "tree")
    rules = tree / "policies" / "rules.py"
    rules.write_text(rules.read_text() + "\nimport pnp_twin.cli.app  # noqa\n")
    out = lint_imports(tree, tmp_path)
    assert out.returncode != 0
    assert "pnp_twin.policies.rules -> pnp_twin.cli.app" in out.stdout


def test_importing_the_core_loads_nothing_above_it() -> None:
    code = (
        "import sys, pnp_twin.twin.line, pnp_twin.twin.camera, pnp_twin.twin.run\n"
        "import pnp_twin.twin.kpis, pnp_twin.twin.stats\n"
        "up = ('torch', 'gymnasium', 'plotly', 'scipy')\n"
        "ours = ('policies', 'reports', 'studies', 'learning', 'cli', 'parallel')\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in up\n"
        "             or m.startswith('pnp_twin.') and m.split('.')[1] in ours))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]", out.stdout


def _top_level_imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module)
    return [n for n in names if n.split(".")[0] in FOLDERS]


def test_nothing_imports_a_folder_by_its_top_level_name() -> None:
    """``import twin`` would load a second copy of the core beside ``pnp_twin.twin`` (and a
    user's own ``twin/`` or ``reports.py`` in place of ours)."""
    roots = [ROOT / n for n in (*PACKAGES, "tests", "bench", "examples")]
    files = [f for r in roots for f in r.rglob("*.py") if "__pycache__" not in f.parts]
    assert len(files) > 100
    found = {str(f.relative_to(ROOT)): bad for f in files if (bad := _top_level_imports(f))}
    assert found == {}


def _packages_in_checkout() -> set[str]:
    """Every folder with an ``__init__.py``, named as the wheel installs it."""
    out = set()
    for folder in PACKAGES:
        prefix = "pnp_twin" if folder == "pnp_twin" else f"pnp_twin.{folder}"
        for init in (ROOT / folder).rglob("__init__.py"):
            if "__pycache__" not in init.parts:
                out.add(".".join((prefix, *init.parent.relative_to(ROOT / folder).parts)))
    return out


def test_every_package_folder_is_mapped_into_the_one_package() -> None:
    """No symbolic links: pyproject lists every package and maps each folder; the wheel and
    an editable install follow it, and so does a checkout imported from its folder."""
    import tomllib

    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapping = setuptools["package-dir"]
    assert {mapping[f"pnp_twin.{f}"] for f in FOLDERS} == set(FOLDERS)
    assert _packages_in_checkout() == set(setuptools["packages"])
    out = subprocess.run(
        [sys.executable, "-c", "import pnp_twin.twin.fast, pnp_twin.policies.hdqn as h; "
         "print(pnp_twin.twin.fast.__file__, h.__file__)"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert str(ROOT / "twin" / "fast") in out.stdout and str(ROOT / "policies") in out.stdout
