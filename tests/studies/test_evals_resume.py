"""``design`` and ``capacity`` journal each run the moment it finishes (``evals/runs.jsonl``),
so an interrupted study resumes without running a finished run again: an exception half-way
through a batch, a line cut short, and a SIGKILLed ``design`` and ``capacity``."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies import calibrate_eval
from pnp_twin.studies.calibrate_eval import EVALS, Evaluator
from pnp_twin.studies.runlog import RUNS_FILE, journalled
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
    assert journalled(tmp_path / "a" / EVALS) == 5
    monkeypatch.setattr(calibrate_eval, "execute", real)
    again = Evaluator(tmp_path / "a", ["SD", "SPT"], SEEDS, ["part_flow"], 1, "simpy")
    resumed = again.runs(scenarios(), ["slow", "fast"])
    assert (again.runs_replayed, again.runs_simulated) == (5, 11)
    whole = Evaluator(tmp_path / "b", ["SD", "SPT"], SEEDS, ["part_flow"], 1, "simpy")
    assert resumed == whole.runs(scenarios(), ["slow", "fast"])
    assert journalled(tmp_path / "a" / EVALS) == 16


def test_a_line_cut_short_is_cut_off_and_its_run_done_again(tmp_path, caplog) -> None:
    ev = Evaluator(tmp_path, ["SD"], SEEDS[:2], ["part_flow"], 1, "simpy")
    first = ev.runs(scenarios()[:1], ["slow"])
    for point in (tmp_path / EVALS).glob("*.json"):
        point.unlink()  # as if killed before the point's file was written
    log = tmp_path / EVALS / RUNS_FILE
    whole = log.read_bytes()
    log.write_bytes(whole[: whole.index(b"\n") + 1] + whole[whole.index(b"\n") + 1 :][:30])
    again = Evaluator(tmp_path, ["SD"], SEEDS[:2], ["part_flow"], 1, "simpy")
    assert "cut short" in caplog.text
    assert again.runs(scenarios()[:1], ["slow"]) == first
    assert (again.runs_replayed, again.runs_simulated) == (1, 1)
    assert log.read_bytes() == whole  # the torn bytes are gone, the run written whole


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
        while journalled(out / EVALS) < runs and study.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        assert study.poll() is None, "the command ended before it could be killed"
        study.send_signal(signal.SIGKILL)
        study.wait()
    finally:
        if study.poll() is None:
            os.killpg(study.pid, signal.SIGKILL)
    return journalled(out / EVALS)


@pytest.mark.parametrize(
    ("args", "answer", "runs"),
    [(DESIGN, "design.json", 4), (CAPACITY, "capacity.json", 4)],
    ids=["design", "capacity"],
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
    lines = (out / EVALS / RUNS_FILE).read_bytes().splitlines()
    keys = [json.loads(line)["key"] for line in lines]
    assert len(keys) == len(set(keys)) == journalled(reference / EVALS)  # each run ran once

    def same(path: Path) -> dict:
        data = json.loads(path.read_text())
        skip = ("wall_time", "command", "simulated", "replayed", "runs_simulated", "runs_replayed")
        return {k: v for k, v in data.items() if k not in skip}

    assert same(out / answer) == same(reference / answer)
