"""Same seed, same results across a refactor: runs two checkouts side by side and compares
what they produce.

    python bench/same_results.py [--before REF] [--keep DIR]
    # REF: a git commit (default: the commit before the layers move, issue 8), or the
    # folder of another checkout (e.g. the working tree with one helper's files reverted)

Compared, each side in its own interpreter with only its own tree on ``PYTHONPATH``:

- for each shipped scenario, ``run --json`` (timings removed), ``--events`` and ``--spans``,
  and the same records from the compiled engine (``--engine fast``);
- ``run paper_baseline --policy hdqn:models/...`` with each shipped checkpoint (events);
- a short sweep's ``results.csv`` / ``summary.csv`` / ``paired.csv`` / ``best.csv``;
- the learning interface: observations and rewards of the epoch driver under all three
  termination schemes, one episode's rollout labels, and 300 steps of the compiled vector env;
- a short training run's ``model.safetensors``;
- the line shapes of :data:`NEW_SHAPES` (kinds, sides, reach, outfeeds), in the working tree
  alone: the SimPy engine's ``--events`` and ``--spans`` against the compiled engine's, each
  scheme.

Each output gets one verdict: ``identical`` (the same bytes); ``same values`` (every value
both sides have is equal, once robots are numbered alike: only columns or keys were added,
removed or renamed); or ``DIFFERENT`` with the columns or keys whose values differ. Other
issues may change output formats or redefine a KPI on purpose, so a ``DIFFERENT`` names what
to check; the part records (``--events``) and state spans (``--spans``) are the simulation
itself. The exit code is 0 only when nothing is ``DIFFERENT``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pandas as pd

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
CHECKPOINTS = ["async", "async_rollout", "single", "sync"]
NEW_SHAPES = [
    "two_sided", "delta_over_belt", "waste_sorting",
    "tray_loading_coflow", "tray_loading_counterflow",
]  # fmt: skip
"""Line shapes the earlier checkout may not know (issues 29, 30): compared engine against engine
in the working tree alone, every termination scheme."""
# run metadata, not results: timings, dates, versions, and which engine ran (issue 12)
VOLATILE = (
    "wall_time",
    "wall_s",
    "elapsed",
    "started_at",
    "finished_at",
    "created",
    "versions",
    "engine",
)

# The learning interface, run in each tree (module paths moved with the layers).
LEARNING_PROBE = """
import hashlib, numpy as np
try:
    from pnp_twin.learning.envs.driver import EpochDriver
    from pnp_twin.learning.rollout import LabelSettings, label_episode
except ImportError:
    from pnp_twin.twin.envs.driver import EpochDriver
    from pnp_twin.policies.hdqn.rollout import LabelSettings, label_episode
from pnp_twin.twin import load_scenario
h = hashlib.sha256()
for term in ("t_continue", "t_all", "t_any"):
    d = EpochDriver("paper_baseline", channels=3, termination=term,
                    overrides={"duration": 20.0, "warmup": 5.0})
    deciding, rng = d.reset(3), np.random.default_rng(0)
    while not d.done:
        for r in deciding:
            h.update(d.observe(r).tobytes() + d.observe(None).tobytes())
            h.update(repr(d.reward(r)).encode())
        deciding = d.act({r: int(rng.integers(5)) for r in deciding})
    h.update(repr(d.gripping_rate()).encode())
print("driver", h.hexdigest())
lab = label_episode(load_scenario("paper_baseline"), 7,
                    LabelSettings(episode_time=6.0, window=(3.0, 4.0), futures=2))
print("labels", hashlib.sha256(lab.obs.tobytes() + lab.robot.tobytes()
                               + lab.advantage.tobytes()).hexdigest())
try:
    from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv
except ImportError:
    PickPlaceVectorEnv = None
if PickPlaceVectorEnv is not None:
    h = hashlib.sha256()
    env = PickPlaceVectorEnv(num_envs=4, overrides={"duration": 20.0, "warmup": 5.0})
    obs, _ = env.reset(seed=5)
    rng = np.random.default_rng(1)
    for _ in range(300):
        obs, rew, term, trunc, _ = env.step(rng.integers(env.single_action_space.n, size=4))
        h.update(np.asarray(obs).tobytes() + np.asarray(rew).tobytes()
                 + np.asarray(term).tobytes() + np.asarray(trunc).tobytes())
    print("vector_env", h.hexdigest())
"""


def cli_module(tree: Path) -> str:
    return "pnp_twin" if (tree / "pnp_twin" / "__main__.py").is_file() else "twin"


def python(tree: Path, args: list[str], cwd: Path) -> str:
    """stdout of ``python ARGS`` with only ``tree`` on the path; stop on failure."""
    env = {"PYTHONPATH": str(tree), "PATH": str(Path(sys.executable).parent), "HOME": str(cwd)}
    out = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{tree}: {' '.join(args)[:200]} failed:\n{out.stderr[-2000:]}")
    return out.stdout


def cli(tree: Path, args: list[str], cwd: Path) -> str:
    return python(tree, ["-m", cli_module(tree), *args], cwd)


def scrub(value: object) -> object:
    """The JSON with volatile fields (timings, dates, versions) removed."""
    if isinstance(value, dict):
        return {k: scrub(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [scrub(v) for v in value]
    return value


def outputs(tree: Path, work: Path) -> dict[str, Path]:
    """name -> file of every compared output of one checkout (written under ``work``)."""
    found: dict[str, Path] = {}
    short = ["--set", "duration=120", "--set", "warmup=20"]
    for name in SCENARIOS:
        ev, sp, js = (work / f"{name}.{k}" for k in ("events.csv", "spans.csv", "json"))
        text = cli(
            tree, ["run", name, "--json", "--events", str(ev), "--spans", str(sp), *short], work
        )
        js.write_text(json.dumps(scrub(json.loads(text)), sort_keys=True, indent=1))
        found[f"run {name} --json"], found[f"run {name} --events"] = js, ev
        found[f"run {name} --spans"] = sp
        fev, fsp = work / f"{name}.fast.events.csv", work / f"{name}.fast.spans.csv"
        fast = ["--engine", "fast", "--events", str(fev), "--spans", str(fsp)]
        cli(tree, ["run", name, *fast, *short], work)
        found[f"run {name} --engine fast --events"] = fev
        found[f"run {name} --engine fast --spans"] = fsp
    for ck in CHECKPOINTS:
        ev = work / f"hdqn_{ck}.events.csv"
        policy = f"hdqn:{ROOT / 'models' / f'paper_baseline__{ck}'}"
        cli(tree, ["run", "paper_baseline", "--policy", policy, "--events", str(ev), *short], work)
        found[f"run --policy hdqn {ck} --events"] = ev
    study = work / "sweep"
    sweep = ["sweep", "paper_27", "--out", str(study), "--set", "sweep.replications=2"]
    cli(tree, sweep + ["--set", "sweep.duration=60", "--set", "sweep.warmup=10"], work)
    for table in ("results.csv", "summary.csv", "paired.csv", "best.csv"):
        found[f"sweep paper_27 {table}"] = study / table
    for line in python(tree, ["-c", LEARNING_PROBE], work).splitlines():
        key, value = line.split()
        (work / f"learning_{key}.txt").write_text(value + "\n")
        found[f"learning interface {key} digest"] = work / f"learning_{key}.txt"
    train = ["train", "paper_baseline", "--out", str(work / "train"), "--steps", "600"]
    cli(tree, train + ["--eval-every", "300", "--eval-seeds", "2", "--device", "cpu"], work)
    (model,) = sorted((work / "train").glob("*/model.safetensors"))
    found["train async 600 steps model.safetensors"] = model
    return found


def engine_pairs(tree: Path, work: Path) -> tuple[dict[str, Path], dict[str, Path]]:
    """The records of each new line shape and scheme on the SimPy engine and on the
    compiled one (two sides of one checkout, compared as two checkouts are)."""
    sides: tuple[dict[str, Path], dict[str, Path]] = ({}, {})
    short = ["--set", "duration=120", "--set", "warmup=20"]
    for name in NEW_SHAPES:
        for scheme in ("t_continue", "t_all", "t_any"):
            for engine, found in zip(("simpy", "fast"), sides, strict=True):
                ev, sp = (work / f"{name}.{scheme}.{engine}.{k}.csv" for k in ("events", "spans"))
                args = ["run", name, "--engine", engine, "--events", str(ev), "--spans", str(sp)]
                cli(tree, [*args, "--set", f"termination={scheme}", *short], work)
                found[f"run {name} {scheme} --events (engines)"] = ev
                found[f"run {name} {scheme} --spans (engines)"] = sp
    return sides


def flat(value: Any, prefix: str = "") -> dict[str, Any]:
    """A JSON value as {dotted.path: leaf}."""
    if isinstance(value, dict):
        return {
            k: v for key, item in value.items() for k, v in flat(item, f"{prefix}{key}.").items()
        }
    if isinstance(value, list):
        return {
            k: v for i, item in enumerate(value) for k, v in flat(item, f"{prefix}{i}.").items()
        }
    return {prefix[:-1]: value}


def renumbered(before: pd.DataFrame, after: pd.DataFrame) -> pd.DataFrame:
    """``before`` with its robot column numbered as ``after``'s (from 0 or from 1)."""
    if "robot" not in before or "robot" not in after:
        return before
    b, a = pd.to_numeric(before["robot"]), pd.to_numeric(after["robot"])
    shift = int(a.min() - b.min()) if len(a) and len(b) else 0
    if shift:
        before = before.copy()
        before["robot"] = ["" if pd.isna(v) else str(int(v) + shift) for v in b]
    return before


def compare_values(before: Path, after: Path) -> tuple[str, list[str]]:
    """(verdict, what differs) of two outputs that are not byte-identical."""
    if before.suffix == ".json":
        b, a = flat(json.loads(before.read_text())), flat(json.loads(after.read_text()))
    elif before.suffix == ".csv":
        bt = pd.read_csv(before, dtype=str, keep_default_na=False)
        at = pd.read_csv(after, dtype=str, keep_default_na=False)
        bt = bt.drop(columns=[c for c in VOLATILE if c in bt])
        at = at.drop(columns=[c for c in VOLATILE if c in at])
        if len(bt) != len(at):
            return "DIFFERENT", [f"{len(bt)} rows before, {len(at)} after"]
        bt = renumbered(bt, at)
        b = {c: bt[c].tolist() for c in bt.columns}
        a = {c: at[c].tolist() for c in at.columns}
    else:
        return "DIFFERENT", ["bytes"]
    changed = sorted(k for k in set(b) & set(a) if b[k] != a[k])
    if changed:
        return "DIFFERENT", changed
    only = [f"-{k}" for k in sorted(set(b) - set(a))] + [f"+{k}" for k in sorted(set(a) - set(b))]
    return "same values", only


def report(old: dict[str, Path], new: dict[str, Path]) -> int:
    """Print one verdict per output; the number of DIFFERENT ones."""
    bad = 0
    print(f"{'output':<46} verdict")
    for key, before in old.items():
        after = new[key]
        if before.read_bytes() == after.read_bytes():
            verdict, notes = "identical", []
        else:
            verdict, notes = compare_values(before, after)
        bad += verdict == "DIFFERENT"
        more = f" ({', '.join(notes[:8])}{', ...' if len(notes) > 8 else ''})" if notes else ""
        print(f"{key:<46} {verdict}{more}")
    return bad


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--before", default=LAYERS_MOVE_PARENT, help="git commit or checkout folder to compare"
    )
    parser.add_argument("--keep", type=Path, help="copy both sides' outputs to this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        given = Path(args.before).is_dir()
        before = Path(args.before).resolve() if given else Path(tmp) / "before"
        if not given:
            subprocess.run(
                ["git", "worktree", "add", "--detach", str(before), args.before],
                cwd=ROOT,
                check=True,
                capture_output=True,
            )
        try:
            sides = []
            for label, tree in (("before", before), ("after", ROOT)):
                work = Path(tmp) / f"work_{label}"
                work.mkdir()
                sides.append(outputs(tree, work))
            bad = report(*sides)
            shapes = Path(tmp) / "work_shapes"
            shapes.mkdir()
            print("\nnew line shapes, SimPy engine (before) against the compiled one (after):")
            pairs = engine_pairs(ROOT, shapes)
            bad += report(*pairs)
            if args.keep:
                for label in ("before", "after"):
                    shutil.copytree(
                        Path(tmp) / f"work_{label}", args.keep / label, dirs_exist_ok=True
                    )
        finally:
            if not given:
                subprocess.run(["git", "worktree", "remove", "--force", str(before)], cwd=ROOT)
                shutil.rmtree(before, ignore_errors=True)
    n = len(sides[0]) + len(pairs[0])
    print(
        f"{n - bad} of {n} outputs have the same values "
        f"(before = {args.before}, after = working tree; new shapes: engine against engine)"
    )
    sys.exit(0 if bad == 0 else 1)


if __name__ == "__main__":
    main()
