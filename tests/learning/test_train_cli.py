"""``pnp-twin train``: every TrainArgs field an option, progress at 80 columns on a terminal
and plain lines off one, Ctrl-C / SIGTERM checkpoint and exit cleanly."""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

pytest.importorskip("torch")

from pnp_twin.cli import app  # noqa: E402
from pnp_twin.cli.train_progress import TrainProgress  # noqa: E402
from pnp_twin.learning.train_args import TrainArgs  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SMALL = [
    "--set",
    "robots.count=2",
    "--set",
    "feeder.rate=5",
    "--episode-time",
    "15",
    "--eval-seeds",
    "2",
    "--eval-duration",
    "10",
]


def test_every_train_args_field_is_an_option_with_its_default_in_help():
    result = CliRunner().invoke(app, ["train", "--help"], terminal_width=200)
    assert result.exit_code == 0
    text = result.output
    for f in fields(TrainArgs):
        if f.name in ("scenario", "overrides"):
            continue
        assert "--" + f.name.replace("_", "-") in text, f.name
    for shown in (
        "[default: 0.00025]",
        "[default: 0.9]",
        "[default: 64",
        "[default: 0.3]",
        "[default: 1000",
        "5 % of steps",
        "steps / 10",
    ):
        assert shown in text, shown


def test_the_progress_bar_fits_80_columns():
    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=80, color_system=None)
    with TrainProgress("train async", 200_000, console=console) as show:
        show.training_row(
            {
                "step": 123_456,
                "gripping_rate": 71.234,
                "epsilon": 0.02,
                "steps_per_s": 1050.0,
                "reward": 0.1,
                "loss": 0.01,
            }
        )
        show.close()
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", buf.getvalue()).replace("\r", "\n")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert lines and all(len(ln) <= 80 for ln in lines)
    assert any("123456/200000" in ln and "G 71.2%" in ln for ln in lines)


def test_off_a_terminal_training_logs_plain_lines(tmp_path, foreign_signal_handlers):
    args = ["train", "paper_baseline", "--out", str(tmp_path), "--steps", "300", *SMALL]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    # training handles SIGINT / SIGTERM itself and gives the caller's handlers back
    for s, handler in foreign_signal_handlers.items():
        assert signal.getsignal(s) is handler, signal.Signals(s).name
    plain = [ln for ln in result.output.splitlines() if ln.startswith("train async: ")]
    assert len(plain) >= 3 and any("300/300 (100%)" in ln or "301/300" in ln for ln in plain)
    assert all("━" not in ln for ln in result.output.splitlines())
    assert result.output.strip().splitlines()[-1].endswith("paper_baseline__async__1")


@pytest.mark.parametrize(
    ("option", "value", "field"),
    [
        ("--gamma", "1.5", "--gamma"),
        ("--eps-fraction", "-0.1", "--eps-fraction"),
        ("--reward-weights", "1", "--reward-weights"),
        ("--rules", "FIFO,EDD", "--rules"),
        ("--eval-every", "0", "--eval-every"),
    ],
)
def test_bad_training_settings_are_one_line(option, value, field, tmp_path):
    args = ["train", "paper_baseline", "--out", str(tmp_path), "--steps", "10", option, value]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {field}")
    assert not any(tmp_path.iterdir())


def test_ctrl_c_checkpoints_and_exits_130_then_resume_finishes(tmp_path):
    cmd = [
        sys.executable,
        "-m",
        "pnp_twin",
        "train",
        "paper_baseline",
        "--out",
        str(tmp_path),
        "--steps",
        "3000",
        "--checkpoint-every",
        "100000",
        *SMALL,
    ]
    proc = subprocess.Popen(
        cmd,
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        text=True,
    )
    log = tmp_path / "paper_baseline__async__1" / "log.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and (not log.is_file() or len(log.read_text()) < 200):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1].startswith("error: interrupted at step ")
    assert "--resume" in err and "Traceback" not in err
    assert (tmp_path / "paper_baseline__async__1" / "resume" / "state.json").is_file()
    again = CliRunner().invoke(app, [*cmd[3:], "--resume"])
    assert again.exit_code == 0, again.output


@pytest.mark.parametrize("holds", ["notes.txt", "paper_baseline.toml"])
def test_train_refuses_an_out_folder_of_other_files_and_writes_nothing(
    tmp_path: Path, holds: str
) -> None:
    """``--out`` is new, empty or a folder of runs; a folder of other files (or the one that
    holds the scenario) is refused in one line before anything is written."""
    out = tmp_path / "out"
    out.mkdir()
    (out / holds).write_text("name = 'paper_baseline'\n" if holds.endswith(".toml") else "x")
    scenario = str(out / holds) if holds.endswith(".toml") else "paper_baseline"
    before = sorted(p.name for p in out.iterdir())
    result = CliRunner().invoke(app, ["train", scenario, "--out", str(out), "--steps", "10"])
    assert result.exit_code == 2
    assert result.output.count("error:") == 1 and "--out" in result.output
    assert sorted(p.name for p in out.iterdir()) == before


def test_train_accepts_a_folder_that_holds_runs(tmp_path: Path) -> None:
    out = tmp_path / "runs"
    (out / "paper_baseline__async__0").mkdir(parents=True)
    (out / "README.txt").write_text("our runs")
    args = ["train", "paper_baseline", "--out", str(out), "--steps", "10", "--seed", "5"]
    args += ["--eval-every", "10", "--eval-seeds", "1", "--set", "duration=20", "--set", "warmup=5"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert (out / "paper_baseline__async__5" / "model.safetensors").is_file()
