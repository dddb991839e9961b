"""Every command of the guide's "Sizing studies and reports" section (docs/guide/studies.md,
moved there from the README) runs to completion,
with the shipped scenarios, as a new user would type it (shorter runs: fewer replications
and simulated seconds, nothing else changed), and leaves what the README says it leaves."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app

ROOT = Path(__file__).resolve().parents[2]
SHORTER = ["--set", "sweep.duration=12", "--set", "sweep.warmup=2", "--replications", "2"]
STUDIES = {"sweep", "size", "mix"}


def readme_commands() -> list[list[str]]:
    """The ``pnp-twin`` lines of the section's bash blocks, comments dropped."""
    text = (ROOT / "docs" / "guide" / "studies.md").read_text(encoding="utf-8")
    section = text.split("## Sizing studies and reports", 1)[1].split("\n## ", 1)[0]
    lines = []
    for block in re.findall(r"```bash\n(.*?)```", section, flags=re.S):
        for line in block.splitlines():
            line = line.split("#", 1)[0].strip()
            if line.startswith("pnp-twin "):
                lines.append(shlex.split(line)[1:])
    return lines


def test_the_section_lists_every_study_command() -> None:
    kinds = {c[0] for c in readme_commands()}
    assert {"sweep", "size", "mix", "report", "export"} <= kinds


@pytest.mark.timeout(1800)  # the suite's longest: every study command, one on Ray (~90 s alone)
def test_every_readme_study_command_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    for args in readme_commands():
        full = args + (SHORTER if args[0] in STUDIES else [])
        result = CliRunner().invoke(app, full)
        assert result.exit_code == 0, (full, result.stderr, result.stdout[-2000:])
        if args[0] in STUDIES:
            out = Path(args[args.index("--out") + 1])
            assert (out / "report.html").is_file() and (out / "summary.csv").is_file()
        if args[0] == "size":  # the layout is a stated choice, not a silent longer belt
            mode = args[args.index("--layout") + 1] if "--layout" in args else "extend"
            assert f"Layout: {mode}." in result.stdout
        if args[0] == "mix":  # the answer, with the paired margin over the runner-up
            assert "Best rule mix: " in result.stdout
    mix = json.loads(Path("studies/mix/mix.json").read_text())
    assert mix["stopped"] in ("budget", "converged") and mix["evaluated"] <= mix["budget"]
    sizing = json.loads(Path("studies/sizing/sizing.json").read_text())
    assert sizing["layout"]["mode"] in ("extend", "share")
    assert any(Path(a[-1]).suffix == ".xlsx" and Path(a[-1]).is_file() for a in readme_commands())
