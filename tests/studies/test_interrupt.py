"""SIGKILL a study at several points, resume it: the same tables, nothing left behind.

Each study runs in its own process session (``start_new_session``) so that every process
it starts (forkserver, resource tracker, workers) can be found afterwards in /proc.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")

ROOT = Path(__file__).resolve().parents[2]
COMMON = ["paper_baseline", "--no-report", "--set", "sweep.warmup=5"]
SWEEP = [
    "sweep", *COMMON, "--replications", "3", "--policy", "SD", "--policy", "FIFO",
    "--set", "sweep.grid={'feeder.rate': [8.0, 12.0]}", "--set", "sweep.duration=300",
]  # fmt: skip
SIZE = [
    "size", *COMMON, "--target", "80", "--replications", "2", "--policy", "SD",
    "--set", "sweep.grid={'robots.count': [2, 3]}", "--set", "sweep.duration=300",
]  # fmt: skip
TABLES = ("summary.csv", "paired.csv", "best.csv")


def session_members(sid: int) -> list[int]:
    """Live processes of session ``sid``."""
    out = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            fields = Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] not in ("Z", "X"):
            out.append(int(d))
    return out


def cli(args: list[str], out: Path, **kw) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "pnp_twin", *args, "--out", str(out), "--workers", "2"]
    return subprocess.Popen(
        cmd, cwd=ROOT, env=env, start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **kw,
    )  # fmt: skip


def journaled(out: Path) -> int:
    """Runs on disk: the rows of the journal's store (each committed as its run finished)."""
    from pnp_twin.studies.journal import journaled as ids

    return len(ids(out / "runs"))


def kill_after(args: list[str], out: Path, runs: int) -> None:
    """Start a study and SIGKILL it once ``runs`` runs are journaled; check nothing stays."""
    study = cli(args, out)
    try:
        deadline = time.monotonic() + 120
        while journaled(out) < runs and study.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert study.poll() is None, "the study ended before it could be killed"
        study.send_signal(signal.SIGKILL)
        study.wait()
        deadline = time.monotonic() + 10
        while session_members(study.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert session_members(study.pid) == [], "processes outlived the killed study"
    finally:
        for pid in session_members(study.pid):
            os.kill(pid, signal.SIGKILL)
        study.stderr.close()


def resume(args: list[str], out: Path) -> dict:
    study = cli(args, out)
    _, err = study.communicate(timeout=300)
    assert study.returncode == 0, err.decode()
    assert session_members(study.pid) == []
    assert not list(out.rglob("*.tmp")) and not (out / ".replaced").exists()
    assert not (out / ".study.lock.json").exists()
    return json.loads((out / "meta.json").read_text())


def assert_same_tables(out: Path, reference: Path) -> None:
    def results(folder: Path) -> pd.DataFrame:
        return pd.read_parquet(folder / "results.parquet").drop(columns="wall_time")

    pd.testing.assert_frame_equal(results(out), results(reference))
    for name in TABLES:
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Uninterrupted sweep and size studies, in-process."""
    from pnp_twin.cli import app

    base = tmp_path_factory.mktemp("reference")
    for args in (SWEEP, SIZE):
        out = base / args[0]
        result = CliRunner().invoke(app, [*args, "--out", str(out), "--workers", "1"])
        assert result.exit_code == 0, result.output
    return base


@pytest.mark.parametrize(("kind", "runs"), [("sweep", 1), ("sweep", 6), ("sweep", 12)])
def test_a_killed_sweep_resumes_to_the_same_tables(reference, tmp_path, kind, runs):
    out = tmp_path / kind
    kill_after(SWEEP, out, runs)
    (out / ".results.parquet.0123456789ab.tmp").write_bytes(b"PAR1")  # a killed final write
    wal = out / "runs" / "runs.sqlite-wal"  # the killed writer's log, not checkpointed
    assert wal.is_file()
    with wal.open("ab") as f:  # a kill in the middle of a commit: half a frame, no checksum
        f.write(b'{"run_id": "p001-FIFO-r02", "point": 1, "feeder.rate": 12.0, "gripp' * 9)
    meta = resume(SWEEP, out)
    assert meta["runs_skipped"] >= runs and meta["runs_skipped"] + meta["runs_executed"] == 12
    assert_same_tables(out, reference / kind)


def test_a_killed_size_study_resumes_to_the_same_answer(reference, tmp_path):
    out = tmp_path / "size"
    kill_after(SIZE, out, 3)
    meta = resume(SIZE, out)
    assert meta["runs_skipped"] >= 3 and meta["runs_skipped"] + meta["runs_executed"] == 8
    assert_same_tables(out, reference / "size")
    sizing = json.loads((out / "sizing.json").read_text())
    assert sizing == json.loads((reference / "size" / "sizing.json").read_text())


def test_a_terminated_sweep_writes_its_finished_runs_and_resumes(reference, tmp_path):
    """SIGTERM (kill, timeout, a scheduler) ends a study as Ctrl-C does: exit 143 with one
    line, every run finished so far on disk, the folder let go, no process left."""
    out = tmp_path / "sweep"
    study = cli(SWEEP, out)
    try:
        deadline = time.monotonic() + 120
        while journaled(out) < 2 and study.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert study.poll() is None, "the study ended before it could be stopped"
        study.send_signal(signal.SIGTERM)
        _, err = study.communicate(timeout=60)
    finally:
        for pid in session_members(study.pid):
            os.kill(pid, signal.SIGKILL)
    assert study.returncode == 143
    assert err.decode().strip().splitlines()[-1] == "error: terminated"  # after the bar
    assert not (out / ".study.lock.json").exists()
    on_disk = journaled(out)
    assert on_disk >= 2
    meta = resume(SWEEP, out)
    assert meta["runs_skipped"] == on_disk and meta["runs_executed"] == 12 - on_disk
    assert_same_tables(out, reference / "sweep")
