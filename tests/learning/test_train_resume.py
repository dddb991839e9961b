"""Exact resume: a training run killed (SIGKILL) or stopped (SIGTERM) at any point and resumed
ends with the same weights, byte for byte, and the same logs as one never stopped."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import asdict
from pathlib import Path

import pytest

pytest.importorskip("torch")
pytest.importorskip("safetensors")

from pnp_twin.learning.train import TrainArgs, TrainingInterrupted, train  # noqa: E402
from pnp_twin.learning.train_args import settled  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TINY = {"robots.count": 2, "feeder.rate": 5.0}
RUN = "paper_baseline__async__1"


def _args(out: Path, **kw) -> TrainArgs:
    base = dict(
        scenario="paper_baseline",
        mode="async",
        out=str(out),
        steps=1200,
        episode_time=15.0,
        learning_starts=100,
        train_every=2,
        batch_size=32,
        buffer_size=2_000,
        eval_every=600,
        eval_seeds=2,
        eval_duration=10.0,
        log_every=100,
        checkpoint_every=150,
        device="cpu",
        overrides=dict(TINY),
    )
    base.update(kw)
    return TrainArgs(**base)


def _rows(path: Path, drop=("steps_per_s", "wall_time")) -> list[dict[str, str]]:
    with path.open() as f:
        return [{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(f)]


def _same_run(a: Path, b: Path) -> None:
    for name in ("model.safetensors", "best/model.safetensors"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert _rows(a / "log.csv") == _rows(b / "log.csv")
    assert _rows(a / "eval.csv") == _rows(b / "eval.csv")
    assert 1200 <= json.loads((a / "meta.json").read_text())["counters"]["step"] <= 1201


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    return train(_args(tmp_path_factory.mktemp("ref")))


def _start(args: TrainArgs) -> subprocess.Popen:
    code = (
        "import json, sys; from pnp_twin.learning.train import TrainArgs, train; "
        "a = json.loads(sys.argv[1]); a['rules'] = tuple(a['rules']); "
        "a['reward_weights'] = tuple(a['reward_weights']); train(TrainArgs(**a))"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, "-c", code, json.dumps(asdict(args))],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )


def _wait_for_checkpoint(proc: subprocess.Popen, folder: Path, step: int) -> int:
    state = folder / "resume" / "state.json"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read().decode()
        try:
            seen = json.loads(state.read_text())["counters"]["step"]
        except (OSError, ValueError):
            seen = 0
        if seen >= step:
            return seen
        time.sleep(0.01)
    raise AssertionError("no checkpoint in time")


def test_a_run_killed_with_sigkill_and_resumed_ends_with_identical_weights(reference, tmp_path):
    args = _args(tmp_path)
    proc = _start(args)
    try:
        seen = _wait_for_checkpoint(proc, tmp_path / RUN, 450)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL and seen < 1200
    folder = train(_args(tmp_path, resume=True))
    _same_run(folder, reference)


def test_sigterm_writes_a_checkpoint_then_stops_and_resume_is_exact(reference, tmp_path):
    proc = _start(_args(tmp_path))
    try:
        _wait_for_checkpoint(proc, tmp_path / RUN, 300)
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 1  # TrainingInterrupted, after its checkpoint
    err = proc.stderr.read().decode()
    assert "TrainingInterrupted" in err and "--resume" in err
    state = json.loads((tmp_path / RUN / "resume" / "state.json").read_text())
    assert 300 <= state["counters"]["step"] < 1200
    _same_run(train(_args(tmp_path, resume=True)), reference)


def test_the_signal_handler_checkpoints_at_once_in_process(tmp_path):
    def stop_soon(row):
        if row["step"] >= 200:
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(TrainingInterrupted) as e:
        train(_args(tmp_path, checkpoint_every=10_000), stop_soon)
    assert e.value.step < 10_000
    state = json.loads((tmp_path / RUN / "resume" / "state.json").read_text())
    assert state["counters"]["step"] == e.value.step  # checkpointed where it stopped


def test_killed_before_its_first_checkpoint_then_resumed_writes_clean_logs(tmp_path):
    folder = tmp_path / RUN
    folder.mkdir()
    # what a run killed before its first checkpoint leaves: rows, no header, no state
    (folder / "log.csv").write_text("step,episode\n100,0\n")
    (folder / "eval.csv").write_text("")
    train(_args(tmp_path, steps=300, eval_every=300, resume=True))
    steps = [int(r["step"]) for r in _rows(folder / "log.csv")]
    assert len(steps) == 3 and steps == sorted(set(steps))  # one row per 100 steps, no repeat
    assert [s // 100 for s in steps] == [1, 2, 3]
    with (folder / "eval.csv").open() as f:
        header = next(csv.reader(f))
    assert header[:2] == ["step", "wall_time"] and "gripping_rate" in header


def test_a_scenario_name_never_leads_outside_out(tmp_path):
    evil = tmp_path / "evil.toml"
    text = (ROOT / "scenarios" / "paper_baseline.toml").read_text()
    text = text.replace('name = "paper_baseline"', 'name = "../../escape"', 1)
    assert "../../escape" in text
    evil.write_text(text)
    out = tmp_path / "out"
    folder = train(_args(out, scenario=str(evil), steps=100, eval_every=100))
    assert folder.resolve().parent == out.resolve()
    assert folder.name == "escape__async__1"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["evil.toml", "out"]
    absolute = text.replace('name = "../../escape"', 'name = "/tmp/abs"', 1)
    evil.write_text(absolute)
    assert train(_args(out, scenario=str(evil), steps=100, eval_every=100)).name == (
        "tmp_abs__async__1"
    )


def test_defaults_scale_with_the_steps():
    short = settled(TrainArgs(steps=2_000))
    assert short.learning_starts == 100 and short.eval_every == 200
    assert short.log_every == 20 and short.checkpoint_every == 100
    paper = settled(TrainArgs())
    assert (paper.learning_starts, paper.eval_every, paper.log_every) == (5_000, 20_000, 1_000)
    assert settled(TrainArgs(learning_starts=7)).learning_starts == 7


def test_without_the_replay_a_resume_still_works_but_says_it_is_not_exact(tmp_path, caplog):
    train(_args(tmp_path, steps=300, eval_every=300, save_replay=False))
    assert not (tmp_path / RUN / "resume" / "replay.npz").exists()
    with caplog.at_level("WARNING"):
        train(_args(tmp_path, steps=450, eval_every=300, save_replay=False, resume=True))
    assert any("not an exact resume" in r.getMessage() for r in caplog.records)
