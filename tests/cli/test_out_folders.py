"""An output folder is ours only by our own marker (a study's ``study.json``, a design's
``design.json``, a lock, ...), never by a common name: a folder holding someone's
``meta.json``, ``runs/`` or ``report.html`` is refused, and nothing in it changes."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app

ROOT = Path(__file__).resolve().parents[2]
SHORT = ["--set", "duration=30", "--set", "warmup=5"]
COMMANDS = {
    "sweep": ["sweep", "two_robot", "--set", "sweep.replications=2", "--fresh"],
    "size": ["size", "two_robot", "--target", "90", "--set", "sweep.replications=2"],
    "capacity": ["capacity", "two_robot", "--target", "90", "-r", "2"],
    "design": ["design", "two_robot", "--target", "90", "--vary", "robots.count=1:2"],
    "calibrate": ["calibrate", "two_robot", "--fit", "robots.pick_time=0:0.2"],
}


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _foreign_folders(tmp: Path) -> list[Path]:
    model = tmp / "model_copy"  # a trained model's folder: meta.json and more
    shutil.copytree(ROOT / "models" / "paper_baseline__sync", model)
    docs = tmp / "userdocs"  # someone's report and notes
    docs.mkdir()
    (docs / "report.html").write_text("<p>my report</p>")
    (docs / "notes.txt").write_text("notes")
    work = tmp / "work"  # someone's runs/ and results
    (work / "runs").mkdir(parents=True)
    (work / "runs" / "exp1.json").write_text("{}")
    (work / "results.csv").write_text("a,b\n1,2\n")
    return [model, docs, work]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_folder_with_common_names_but_no_marker_of_ours_is_refused(
    tmp_path: Path, command: str
) -> None:
    args = COMMANDS[command]
    if command == "calibrate":
        targets = tmp_path / "targets.csv"
        targets.write_text("feeder.rate,gripping_rate\n3,95\n4,90\n")
        args = [*args, "--targets", str(targets)]
    for folder in _foreign_folders(tmp_path):
        before = _snapshot(folder)
        result = CliRunner().invoke(app, [*args, "--out", str(folder)])
        assert result.exit_code == 2, (folder.name, result.output)
        assert result.output.count("error:") == 1 and "no study of ours" in result.output
        assert _snapshot(folder) == before, folder.name
