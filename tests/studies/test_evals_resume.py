"""``design`` and ``capacity`` store each run the moment it finishes (``evals/runs.sqlite``),
so an interrupted study resumes without running a finished run again: an exception half-way
through a batch, an older folder's log (a line cut short included) migrated, and a SIGKILLed
``design`` and ``capacity``."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies import calibrate_eval
from pnp_twin.studies.calibrate_eval import EVALS, Evaluator
from pnp_twin.studies.runstore import STORE_FILE, stored_runs
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario, with_overrides

ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "scenarios" / "paper_baseline.toml"
LINE = {"robots.count": 2, "feeder.rate": 4.0, "duration": 40.0, "warmup": 5.0, "seed": 5}
SETS = [x for k, v in LINE.items() for x in ("--set", f"{k}={v}")]
DESIGN = [
    "design", str(BASELINE), "--target", "90", "--vary", "robots.count=1:3",
    "--vary", "robots.arm_speed=2.0,4.0", "-p", "SD", "-p", "SPT", "-r", "3",
    "--max-replications", "6", "--engine", "simpy", "--no-report", *SETS,
]  # fmt: skip
CAPACITY = [
    "capacity", str(BASELINE), "--target", "85", "-p", "SD", "-p", "SPT", "-r", "3",
    "--engine", "simpy", "--no-report", *SETS,
]  # fmt: skip
HEADROOM = [
    "headroom",
    str(BASELINE),
    "--seeds",
    "3",
    "--duration",
    "30",
    "--engine",
    "simpy",
    "--lookahead",
    "lookahead:K=2,H=1,base=SD",
    *SETS,
]  # fmt: skip  (the mix searched on tuning seeds: ~100 runs, killed in the search)
SEEDS = replication_seeds(5, 4)


class Stop(BaseException):
    """Stands for a kill half-way through a batch."""


def scenarios() -> list:
    sc = load_scenario(BASELINE, overrides=LINE)
    return [with_overrides(sc, {"feeder.rate": r}) for r in (3.0, 5.0)]


def test_a_batch_cut_short_keeps_its_finished_runs(tmp_path, monkeypatch) -> None:
    """Two points x two rules x four seeds (16 runs): stopped after 5, the 5 are on disk and
    the rerun simulates only the other 11, to the same answer as an uninterrupted one."""
    real = calibrate_eval.execute
    done: list[str] = []

    def stopping(spec):
        if len(done) == 5:
            raise Stop
        done.append(spec.run_id)
        return real(spec)

    monkeypatch.setattr(calibrate_eval, "execute", stopping)
    ev = Evaluator(tmp_path / "a", ["SD", "SPT"], SEEDS, ["part_flow"], 1, "simpy")
    with pytest.raises(Stop):
        ev.runs(scenarios(), ["slow", "fast"])
    assert stored_runs(tmp_path / "a" / EVALS) == 5
    monkeypatch.setattr(calibrate_eval, "execute", real)
    again = Evaluator(tmp_path / "a", ["SD", "SPT"], SEEDS, ["part_flow"], 1, "simpy")
    resumed = again.runs(scenarios(), ["slow", "fast"])
    assert (again.runs_replayed, again.runs_simulated) == (5, 11)
    whole = Evaluator(tmp_path / "b", ["SD", "SPT"], SEEDS, ["part_flow"], 1, "simpy")
    assert resumed == whole.runs(scenarios(), ["slow", "fast"])
    assert stored_runs(tmp_path / "a" / EVALS) == 16


def test_an_older_log_is_migrated_once_and_its_cut_line_run_again(tmp_path, caplog) -> None:
    """An earlier version's ``runs.jsonl`` (its last line cut short by a kill) is imported
    into the store on first open and renamed: its whole run is replayed, the cut one run."""
    ev = Evaluator(tmp_path, ["SD"], SEEDS[:2], ["part_flow"], 1, "simpy")
    first = ev.runs(scenarios()[:1], ["slow"])
    for point in (tmp_path / EVALS).glob("*.json"):
        point.unlink()  # as if killed before the point's file was written
    db = sqlite3.connect(tmp_path / EVALS / STORE_FILE)
    rows = db.execute("SELECT key, kpis FROM runs ORDER BY rowid").fetchall()
    db.close()
    ev.store.close()
    for suffix in ("", "-wal", "-shm"):
        (tmp_path / EVALS / (STORE_FILE + suffix)).unlink(missing_ok=True)
    lines = [f'{{"key": "{k}", "row": {v}}}\n' for k, v in rows]
    log = tmp_path / EVALS / "runs.jsonl"
    log.write_text(lines[0] + lines[1][:30])  # the second line's write was cut short
    again = Evaluator(tmp_path, ["SD"], SEEDS[:2], ["part_flow"], 1, "simpy")
    assert "cut short" in caplog.text
    assert not log.exists() and (tmp_path / EVALS / "runs.jsonl.migrated").is_file()
    assert again.runs(scenarios()[:1], ["slow"]) == first
    assert (again.runs_replayed, again.runs_simulated) == (1, 1)
    assert stored_runs(tmp_path / EVALS) == 2
    third = Evaluator(tmp_path, ["SD"], SEEDS[:2], ["part_flow"], 1, "simpy")
    assert len(third.store) == 2  # the renamed log is not imported again


def cli(args: list[str], out: Path) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "pnp_twin", *args, "--out", str(out), "--workers", "1"]
    return subprocess.Popen(
        cmd, cwd=ROOT, env=env, start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip


def kill_after(args: list[str], out: Path, runs: int) -> int:
    """SIGKILL the command once ``runs`` runs are journalled; how many were."""
    study = cli(args, out)
    try:
        deadline = time.monotonic() + 120
        while stored_runs(out / EVALS) < runs and study.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        assert study.poll() is None, "the command ended before it could be killed"
        study.send_signal(signal.SIGKILL)
        study.wait()
    finally:
        if study.poll() is None:
            os.killpg(study.pid, signal.SIGKILL)
    return stored_runs(out / EVALS)


@pytest.mark.parametrize(
    ("args", "answer", "runs"),
    [(DESIGN, "design.json", 4), (CAPACITY, "capacity.json", 4), (HEADROOM, "headroom.json", 30)],
    ids=["design", "capacity", "headroom"],
)
def test_a_killed_study_resumes_without_running_a_finished_run_again(
    tmp_path, args, answer, runs
) -> None:
    reference = tmp_path / "reference"
    result = CliRunner().invoke(app, [*args, "--out", str(reference), "--workers", "1"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "killed"
    before = kill_after(args, out, runs)
    assert before >= runs and not (out / answer).exists()
    result = CliRunner().invoke(app, [*args, "--out", str(out), "--workers", "1", "--json"])
    assert result.exit_code == 0, result.output
    db = sqlite3.connect(out / EVALS / STORE_FILE)
    count, last = db.execute("SELECT count(*), max(rowid) FROM runs").fetchone()
    db.close()
    # each run ran once: a run stored again replaces its row under a new rowid
    assert count == last == stored_runs(reference / EVALS)
    assert not list((out / EVALS).glob("runs.jsonl*"))

    def same(data: object) -> object:
        """Without what differs between any two runs: timings, the command, the counts."""
        skip = ("wall_time", "command", "simulated", "replayed", "cpu_ms_per_decision")
        skip += ("runs_simulated", "runs_replayed")
        if isinstance(data, dict):
            return {k: same(v) for k, v in data.items() if k not in skip}
        return [same(v) for v in data] if isinstance(data, list) else data

    assert same(json.loads((out / answer).read_text())) == same(
        json.loads((reference / answer).read_text())
    )
    if (reference / "runs.csv").is_file():  # headroom: every run's figure, bit for bit
        assert (out / "runs.csv").read_bytes() == (reference / "runs.csv").read_bytes()
