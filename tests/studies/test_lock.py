"""A study folder has one writer: a second study into a held --out is refused at once.

The first study is paused (SIGSTOP) while it holds the lock, so the test does not depend on
how fast the machine runs it; it is resumed (SIGCONT) afterwards and must finish whole.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from pnp_twin.studies.journal import journaled

ROOT = Path(__file__).resolve().parents[2]
RUNS = 3 * 2 * 4  # rates x policies x replications


def sweep_args(out: Path) -> list[str]:
    return [
        sys.executable, "-m", "pnp_twin", "sweep", "paper_baseline", "--out", str(out),
        "--workers", "1", "--no-report", "--replications", "4",
        "--policy", "SD", "--policy", "FIFO",
        "--set", "sweep.grid={'feeder.rate': [8.0, 10.0, 12.0]}",
        "--set", "sweep.duration=100", "--set", "sweep.warmup=5",
    ]  # fmt: skip


def start(args: list[str]) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        args, cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )


def test_a_second_study_into_a_held_folder_is_refused_and_the_first_finishes(tmp_path):
    out = tmp_path / "study"
    first = start(sweep_args(out))
    try:
        deadline = time.monotonic() + 60
        while not (out / ".study.lock.json").exists() and time.monotonic() < deadline:
            assert first.poll() is None, first.communicate()
            time.sleep(0.05)
        first.send_signal(signal.SIGSTOP)  # it holds the lock, however fast this machine is
        seconds = []
        for extra in ([], ["--fresh"]):  # a plain rerun, and one that would wipe the folder
            t0 = time.monotonic()
            second = start(sweep_args(out) + extra)
            _, err = second.communicate(timeout=60)
            seconds.append(time.monotonic() - t0)
            assert second.returncode == 2, err
            lines = err.strip().splitlines()
            assert len(lines) == 1, err
            assert lines[0].startswith(f"error: --out {out}: in use by pid {first.pid} on ")
            assert socket.gethostname() in lines[0] and "(pnp-twin sweep paper_baseline" in lines[0]
            assert " since 20" in lines[0] and "wait for it to finish" in lines[0]
        assert first.poll() is None
        first.send_signal(signal.SIGCONT)
        _, err = first.communicate(timeout=300)
        assert first.returncode == 0, err
    finally:
        if first.poll() is None:
            first.send_signal(signal.SIGCONT)
            first.kill()
            first.wait()
    df = pd.read_parquet(out / "results.parquet")
    assert len(df) == RUNS and df["run_id"].is_unique
    assert len(journaled(out / "runs")) == RUNS
    assert len(pd.read_csv(out / "summary.csv")) == 6 and (out / "meta.json").exists()
    assert not (out / ".study.lock.json").exists()
    assert not list(out.rglob(".*.tmp")) and not (out / ".replaced").exists()
    # "at once": the refusal costs about one interpreter start, not the first study's runs
    assert max(seconds) < 30
