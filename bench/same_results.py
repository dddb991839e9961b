"""Same seed, same results across a refactor: runs the command line of two checkouts side by
side and compares what they write, byte for byte.

    python bench/same_results.py --before REF          # REF: a git commit (default: the
                                                       # commit before the layers move)

For each shipped scenario: ``run --json`` (wall time removed), ``--events`` and ``--spans``;
then a short sweep's ``results.csv`` / ``summary.csv`` / ``paired.csv``; then a short training
run's ``model.safetensors``. The "before" tree is a temporary git worktree of REF; each side
runs in its own interpreter with only its own tree on ``sys.path``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS_MOVE_PARENT = "485900e"  # main before the one-way layers move (issue 8)
SCENARIOS = [
    "paper_baseline",
    "two_robot",
    "trace_replay",
    "breakdowns",
    "paper_27",
    "sizing_example",
    "rule_mix",
]
VOLATILE = ("wall_time", "wall_s", "elapsed", "started_at", "finished_at", "created", "versions")


def cli_module(tree: Path) -> str:
    return "pnp_twin" if (tree / "pnp_twin" / "__main__.py").is_file() else "twin"


def cli(tree: Path, args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {"PYTHONPATH": str(tree), "PATH": str(Path(sys.executable).parent), "HOME": str(cwd)}
    cmd = [sys.executable, "-m", cli_module(tree), *args]
    out = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{tree}: {' '.join(args)} failed:\n{out.stderr[-2000:]}")
    return out


def scrub(value: object) -> object:
    """The JSON with volatile fields (timings, dates, versions) removed."""
    if isinstance(value, dict):
        return {k: scrub(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [scrub(v) for v in value]
    return value


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def outputs(tree: Path, work: Path) -> dict[str, str]:
    """name -> digest of every compared output of one checkout."""
    found: dict[str, str] = {}
    for name in SCENARIOS:
        ev, sp = work / f"{name}.events.csv", work / f"{name}.spans.csv"
        args = ["run", name, "--json", "--events", str(ev), "--spans", str(sp)]
        text = cli(tree, args + ["--set", "duration=120", "--set", "warmup=20"], work).stdout
        kpis = json.dumps(scrub(json.loads(text)), sort_keys=True)
        found[f"run {name} --json"] = hashlib.sha256(kpis.encode()).hexdigest()[:16]
        found[f"run {name} --events"] = digest(ev)
        found[f"run {name} --spans"] = digest(sp)
    study = work / "sweep"
    sweep = ["sweep", "paper_27", "--out", str(study), "--set", "sweep.replications=2"]
    cli(tree, sweep + ["--set", "sweep.duration=60", "--set", "sweep.warmup=10"], work)
    for table in ("results.csv", "summary.csv", "paired.csv", "best.csv"):
        found[f"sweep paper_27 {table}"] = digest(study / table)
    train = ["train", "paper_baseline", "--out", str(work / "train"), "--steps", "600"]
    cli(tree, train + ["--eval-every", "300", "--eval-seeds", "2", "--device", "cpu"], work)
    (model,) = sorted((work / "train").glob("*/model.safetensors"))
    found["train async 600 steps model.safetensors"] = digest(model)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default=LAYERS_MOVE_PARENT, help="git commit to compare")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        before = Path(tmp) / "before"
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(before), args.before],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
        try:
            results = []
            for label, tree in (("before", before), ("after", ROOT)):
                work = Path(tmp) / f"work_{label}"
                work.mkdir()
                results.append(outputs(tree, work))
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(before)], cwd=ROOT)
            shutil.rmtree(before, ignore_errors=True)
    old, new = results
    same = 0
    print(f"{'output':<44} {'before':<17} {'after':<17} same")
    for key in old:
        ok = old[key] == new.get(key)
        same += ok
        print(f"{key:<44} {old[key]:<17} {new.get(key, '-'):<17} {'yes' if ok else 'NO'}")
    print(f"{same} of {len(old)} outputs identical (before = {args.before}, after = working tree)")
    sys.exit(0 if same == len(old) else 1)


if __name__ == "__main__":
    main()
