"""The runs journal of ``design``: a continuous design of ~3,000 points, run and asked again,
before (``evals/runs.jsonl``, re-read per batch) and after (``evals/runs.sqlite``).

    python bench/bench_journal.py [--before REF] [--points 3000] [--quick] [--keep DIR]
    # REF: a git commit (default 29096cf, the last commit with the jsonl log) or the folder
    # of another checkout

The design: ``paper_baseline`` with ``robots.count=1:8`` (8 values) x the rules SD, SPT, FIFO
x ``--trials`` points of the continuous ``robots.arm_speed=2.0:6.0`` (POINTS / 24 trials),
2 replications each (``-r 2 --max-replications 2``), 10 s runs, the compiled engine, one
worker. Timed, each side in its own interpreter with only its own tree on ``PYTHONPATH``:

- **first run**: into an empty folder;
- **asked again**: the same command on the finished folder (nothing to simulate). The before
  side asks the after side's finished folder with its store written out as ``runs.jsonl``
  (the format the before side writes; the points' files are the same), so ``--quick`` can
  skip the before side's slow first run;
- **migrate + ask again**: the after side on a copy of that jsonl folder (the log imported
  into ``runs.sqlite`` once, then optuna's search replayed over the stored runs: a folder of
  the before side holds no question key, so its answer is not read back).

Both sides' ``design.json`` (timings and counts aside) must be equal; the exit code is 1 if not.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "29096cf"  # the last commit whose design journals runs in evals/runs.jsonl
GROUPS = 8 * 3  # robot counts x rules: optuna's searches, each of --trials points
VOLATILE = ("wall_time", "command", "simulated", "replayed", "question")


def design_args(out: Path, trials: int) -> list[str]:
    return [
        "design", "paper_baseline", "--target", "90",
        "--vary", "robots.count=1:8", "--vary", "robots.arm_speed=2.0:6.0",
        "-p", "SD", "-p", "SPT", "-p", "FIFO", "--trials", str(trials),
        "-r", "2", "--max-replications", "2", "--set", "duration=10", "--set", "warmup=2",
        "--engine", "fast", "--workers", "1", "--no-report", "--json", "--out", str(out),
    ]  # fmt: skip


def timed(tree: Path, out: Path, trials: int) -> tuple[float, dict[str, Any]]:
    """Seconds the design took with ``tree``'s code, and its JSON answer."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, "-m", "pnp_twin", *design_args(out, trials)]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"{tree}: design failed ({done.returncode}): {done.stderr.strip()[-400:]}")
    return seconds, json.loads(done.stdout)


def as_jsonl(folder: Path, into: Path) -> None:
    """``folder`` (a finished design) with its store written out as the before side's
    ``evals/runs.jsonl``: one ``{"key": ..., "row": {...}}`` line per run, in run order."""
    shutil.copytree(folder, into, ignore=shutil.ignore_patterns("runs.sqlite*"))
    answer = json.loads((into / "design.json").read_text(encoding="utf-8"))
    answer.pop("question", None)  # as the before side wrote it: the search runs again
    (into / "design.json").write_text(json.dumps(answer), encoding="utf-8")
    db = sqlite3.connect(folder / "evals" / "runs.sqlite")
    rows = db.execute("SELECT key, kpis FROM runs ORDER BY rowid").fetchall()
    db.close()
    with open(into / "evals" / "runs.jsonl", "w", encoding="utf-8") as f:
        for key, kpis in rows:
            row = {k: float("nan") if v is None else v for k, v in json.loads(kpis).items()}
            f.write(json.dumps({"key": key, "row": row}) + "\n")


def same(answer: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in answer.items() if k not in VOLATILE}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default=BEFORE, help="git commit or checkout folder")
    parser.add_argument("--points", type=int, default=3000, help="points the design evaluates")
    parser.add_argument("--quick", action="store_true", help="skip the before side's first run")
    parser.add_argument("--keep", type=Path, help="copy the study folders here")
    args = parser.parse_args()
    trials = max(1, round(args.points / GROUPS))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        given = Path(args.before).is_dir()
        before = Path(args.before).resolve() if given else work / "before_tree"
        if not given:
            subprocess.run(
                ["git", "worktree", "add", "--detach", str(before), args.before],
                cwd=ROOT, check=True, capture_output=True,
            )  # fmt: skip
        try:
            times, answers = {}, {}
            print(f"design of {GROUPS * trials} points ({GROUPS} searches x {trials} trials)")
            times["after first"], answers["after"] = timed(ROOT, work / "after", trials)
            print(f"  after, first run:      {times['after first']:8.1f} s", flush=True)
            times["after again"], _ = timed(ROOT, work / "after", trials)
            print(f"  after, asked again:    {times['after again']:8.1f} s", flush=True)
            as_jsonl(work / "after", work / "jsonl")
            shutil.copytree(work / "jsonl", work / "migrate")
            times["before again"], answers["before"] = timed(before, work / "jsonl", trials)
            print(f"  before, asked again:   {times['before again']:8.1f} s", flush=True)
            times["migrate"], answers["migrated"] = timed(ROOT, work / "migrate", trials)
            print(f"  after, migrate + ask:  {times['migrate']:8.1f} s", flush=True)
            if not args.quick:
                times["before first"], answers["before"] = timed(before, work / "bf", trials)
                print(f"  before, first run:     {times['before first']:8.1f} s", flush=True)
            if args.keep:
                shutil.copytree(work, args.keep, dirs_exist_ok=True, ignore=_trees)
        finally:
            if not given:
                subprocess.run(["git", "worktree", "remove", "--force", str(before)], cwd=ROOT)
    report(times, answers, args.before, GROUPS * trials)


def _trees(folder: str, names: list[str]) -> list[str]:
    return ["before_tree"] if "before_tree" in names else []


def report(times: dict[str, float], answers: dict[str, Any], before: str, points: int) -> None:
    simulated = answers["after"]["simulated"]
    print(f"\n{points} points, {simulated} runs simulated; before = {before}, after = this tree")
    print(f"{'':22}{'before':>10}{'after':>10}{'before/after':>14}")
    for what, b, a in (
        ("first run", "before first", "after first"),
        ("asked again", "before again", "after again"),
    ):
        if b in times:
            ratio = times[b] / times[a]
            print(f"{what:22}{times[b]:9.1f}s{times[a]:9.1f}s{ratio:13.1f}x")
        else:
            print(f"{what:22}{'(--quick)':>10}{times[a]:9.1f}s")
    print(f"{'migrate + ask again':22}{'':>10}{times['migrate']:9.1f}s")
    equal = all(same(a) == same(answers["after"]) for a in answers.values())
    print(f"design.json the same on every side: {'yes' if equal else 'NO'}")
    if not equal:
        sys.exit(1)


if __name__ == "__main__":
    main()
