"""The user guide (mkdocs.yml, docs/): it builds strictly, every command its getting-started
pages show runs, its reference pages are what their sources generate, every relative link
of the guide and the README points at a file of the repository, and the README stays short."""

from __future__ import annotations

import importlib.util
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
STARTED = [DOCS / "plant-engineers.md", DOCS / "researchers.md"]
SETUP = [
    "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/pnp-twin run paper_baseline",
    "python3 -m venv .venv && .venv/bin/pip install torch==2.13.0 && .venv/bin/pip install -e "
    "'.[test]' && .venv/bin/pytest",
]


def page_commands(page: Path) -> list[list[str]]:
    """The ``pnp-twin`` lines of the page's bash blocks, comments dropped."""
    text = page.read_text(encoding="utf-8")
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            line = line.split("#", 1)[0].strip()
            if line.startswith("pnp-twin "):
                out.append(shlex.split(line)[1:])
    return out


@pytest.mark.timeout(300)
def test_every_getting_started_command_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    commands = [c for page in STARTED for c in page_commands(page)]
    assert {c[0] for c in commands} >= {"validate", "run", "compare", "size", "task"}
    start = time.perf_counter()
    for args in commands:
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, (args, result.output[-2000:])
    assert Path("run.html").is_file() and Path("compare.html").is_file()
    assert Path("sizing/report.html").is_file()
    assert time.perf_counter() - start < 120  # about 30 s on a 2-core machine


@pytest.mark.timeout(300)
def test_the_readme_tour_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The README's tour, as written: each command but the studies (``--out``: minutes each;
    their scenarios are validated instead) runs and writes what it names."""
    monkeypatch.chdir(tmp_path)
    commands = page_commands(ROOT / "README.md")
    assert {c[0] for c in commands} >= {"list", "run", "compare", "size", "sweep"}
    for args in commands:
        quick = "--out" not in args
        result = CliRunner().invoke(app, args if quick else ["validate", args[1]])
        assert result.exit_code == 0, (args, result.output[-2000:])
    assert all(Path(f).stat().st_size > 0 for f in ("run.html", "line.gif", "cmp.html"))


def test_the_reference_pages_are_up_to_date() -> None:
    spec = importlib.util.spec_from_file_location("make_reference", DOCS / "make_reference.py")
    assert spec is not None and spec.loader is not None
    make = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make)
    assert make.CLI_PAGE.read_text(encoding="utf-8") == make.cli_page(), (
        "run python docs/make_reference.py"
    )
    assert make.SCENARIO_PAGE.read_text(encoding="utf-8") == make.scenario_page()
    assert "## `pnp-twin compare`" in make.cli_page()


def links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return re.findall(r"\]\(([^)\s]+)\)", text)


@pytest.mark.parametrize(
    "page", [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))], ids=lambda p: p.name
)
def test_every_relative_link_points_into_the_repository(page: Path) -> None:
    for target in links(page):
        if target.startswith(("http://", "https://", "mailto:", "#")):
            continue
        path = (page.parent / target.split("#", 1)[0]).resolve()
        assert path.exists(), f"{page.relative_to(ROOT)}: {target}"
        assert ROOT in path.parents or path == ROOT, f"{page.relative_to(ROOT)}: {target}"


def test_the_readme_keeps_the_setup_and_stays_short() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split("```bash\n", 1)[1].split("```", 1)[0].splitlines()
    assert block == SETUP
    assert len(text.splitlines()) <= 250


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None, reason="mkdocs not installed")
@pytest.mark.timeout(300)
def test_the_guide_builds_strictly(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)]
    result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=280)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "plant-engineers" / "index.html").is_file()
