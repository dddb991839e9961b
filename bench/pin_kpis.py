"""Pin the shipped scenarios' KPIs and the README's figures, so that neither drifts unnoticed.

    .venv/bin/python bench/pin_kpis.py            # rewrite tests/pinned/kpis.json, check README
    .venv/bin/python bench/pin_kpis.py --check    # recompute; exit 1 if anything differs
    .venv/bin/python bench/pin_kpis.py --short    # only the short runs (seconds)

Run it when the model changes on purpose, then update the README from what it prints.

- **short runs** (``short``): every shipped scenario for 60 s (warm-up 10 s), its own
  policy, seed 1, on the SimPy reference engine, and ``paper_baseline`` under each of the six
  rules; their KPIs are stored to the last bit. ``tests/twin/test_pinned_kpis.py`` reruns them
  (a few seconds) and compares with a 1e-12 relative tolerance.
- **the README's figures** (``readme``; minutes on one core): the rule ranking at the
  baseline (600 s runs, seeds 0-2, as ``scenarios/paper_baseline.toml`` says) and the
  calibration table (the README's two ``pnp-twin sweep`` commands: arm 2, 3, 4 m/s x six
  rules x 5 replications, the best rule's mean and 95 % CI, and its residual to the paper's
  Fig. 14). They are stored with the text the README must hold; the script checks that
  README.md holds it (exit 1 with the expected lines when not; it never edits README.md) and
  the test checks the same on every run, without simulating.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PINNED = ROOT / "tests" / "pinned" / "kpis.json"
README = ROOT / "docs" / "guide" / "your-line.md"  # the figures' page (once in README.md)

RULES = ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT")
SHIPPED = (
    "paper_baseline",
    "two_robot",
    "trace_replay",
    "breakdowns",
    "paper_27",
    "sizing_example",
    "rule_mix",
    "two_sided",
    "delta_over_belt",
    "waste_sorting",
    "tray_loading_coflow",
    "tray_loading_counterflow",
)
SHORT = {"duration": 60.0, "warmup": 10.0}
SHORT_SEED = 1
KPI_KEYS = (
    "gripping_rate",
    "parts_presented",
    "parts_picked",
    "parts_missed",
    "throughput",
    "max_throughput",
    "efficiency",
    "utilisation",
    "cycle_time_mean",
    "cycle_time_p95",
    "cycle_time_max",
)
ROBOT_KEYS = ("picks", "utilisation", "noop", "blocked", "down", "passed_on")
OUTFEED_KEYS = ("containers", "containers_full", "fill_rate", "parts_held", "hold_time")
"""Pinned too on a line with an outfeed (its runs' KPIs have them; no other line's do)."""

# The README's calibration table: the paper's Fig. 14 and the two sweeps it compares.
PAPER = {2.0: 47.0, 3.0: 72.0, 4.0: 82.0}
ARM_SWEEP = [
    "--set",
    "sweep.grid={robots.arm_speed: [2, 3, 4]}",
    "--set",
    "sweep.policies=[FIFO, LIFO, SIRO, SD, LD, SPT]",
    "--set",
    "sweep.replications=5",
]
BEFORE = [
    "--set",
    "robots.pick_time=0.12",
    "--set",
    "robots.place_time=0.12",
    "--set",
    "robots.bin_offset=[0.0, 0.25]",
    "--set",
    "robots.workspace_length=0.5",
]
TABLE_ROWS = {
    "calibrated": "| `paper_baseline` (calibrated) |",
    "before": "| the line before (grip 0.12 s, bin 0.25 m, workspaces 0.5 m) |",
}


def short_runs() -> list[dict[str, Any]]:
    """The short runs pinned exactly: (scenario, policy) pairs, settings in SHORT."""
    runs = [{"scenario": name, "policy": None} for name in SHIPPED]
    runs += [{"scenario": "paper_baseline", "policy": rule} for rule in RULES]
    return runs


def short_kpis(scenario: str, policy: str | None) -> dict[str, Any]:
    """KPI_KEYS and per-robot ROBOT_KEYS of one short run (None: the scenario's policy)."""
    from pnp_twin.policies import make_policy
    from pnp_twin.twin import load_scenario, simulate, with_overrides

    sc = with_overrides(load_scenario(scenario), dict(SHORT))
    chosen = make_policy(policy or sc.policy, sc.robots.count)
    k = simulate(sc, chosen, seed=SHORT_SEED, engine="simpy").kpis
    out: dict[str, Any] = {key: k[key] for key in KPI_KEYS}
    if "fill_rate" in k:
        out.update({key: k[key] for key in OUTFEED_KEYS})
        out["robots"] = [{key: r[key] for key in (*ROBOT_KEYS, "hold")} for r in k["robots"]]
        return out
    out["robots"] = [{key: r[key] for key in ROBOT_KEYS} for r in k["robots"]]
    return out


def rule_ranking() -> dict[str, float]:
    """Mean gripping rate of each rule on paper_baseline as shipped, seeds 0-2 (the README)."""
    from pnp_twin.policies import make_policy
    from pnp_twin.twin import load_scenario, simulate

    sc = load_scenario("paper_baseline")
    out = {}
    for rule in RULES:
        g = [simulate(sc, make_policy(rule), seed=s).kpis["gripping_rate"] for s in (0, 1, 2)]
        out[rule] = sum(g) / len(g)
    return out


def arm_sweep(extra: list[str], workers: int, engine: str) -> dict[str, dict[str, Any]]:
    """The README's arm-speed sweep (with ``extra`` settings): the best rule per arm speed."""
    import pandas as pd

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "study"
        cmd = [sys.executable, "-m", "pnp_twin", "sweep", "paper_baseline", *extra, *ARM_SWEEP]
        cmd += ["--out", str(out), "--workers", str(workers), "--no-report", "--engine", engine]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        summary = pd.read_csv(out / "summary.csv")
        best = pd.read_csv(out / "best.csv")
    rows = {}
    for _, b in best.iterrows():
        arm = float(b["robots.arm_speed"])
        s = summary[(summary["point"] == b["point"]) & (summary["policy"] == b["policy"])]
        rows[f"{arm:g}"] = {
            "policy": str(b["policy"]),
            "mean": float(s["gripping_rate_mean"].iloc[0]),
            "ci_low": float(s["gripping_rate_ci_low"].iloc[0]),
            "ci_high": float(s["gripping_rate_ci_high"].iloc[0]),
            "paper": PAPER[arm],
        }
    return rows


def readme_text(readme: Mapping[str, Any]) -> list[str]:
    """What README.md must hold for the pinned figures, in this order: each rule's mean in
    the ranking sentence (best first), then the calibration table's two rows."""
    r = readme["ranking"]
    out = [f"{rule} {r[rule]:.1f} %" for rule in sorted(r, key=lambda k: -r[k])]
    for key, head in TABLE_ROWS.items():
        cells = []
        for arm in ("2", "3", "4"):
            c = readme["calibration"][key][arm]
            diff = c["mean"] - c["paper"]
            sign = "+" if diff >= 0 else "\u2212"
            cells.append(
                f"{c['mean']:.2f} [{c['ci_low']:.2f}, {c['ci_high']:.2f}] ({c['policy']}), "
                f"{sign}{abs(diff):.2f}"
            )
        out.append(head + " " + " | ".join(cells) + " |")
    return out


def readme_holds(lines: list[str], text: str) -> list[str]:
    """The expected ``lines`` that README.md's ``text`` does not hold in that order (line
    breaks read as spaces)."""
    flat = " ".join(text.split())
    missing, at = [], 0
    for line in lines:
        found = flat.find(" ".join(line.split()), at)
        if found < 0:
            missing.append(line)
        else:
            at = found + 1
    return missing


def differences(got: Any, want: Any, where: str = "") -> list[str]:
    """Where two pinned structures differ (floats to a relative 1e-12)."""
    if isinstance(want, dict) and isinstance(got, dict):
        out = [f"{where}.{k}: missing" for k in want if k not in got]
        for k in want:
            if k in got:
                out += differences(got[k], want[k], f"{where}.{k}")
        return out
    if isinstance(want, list) and isinstance(got, list):
        if len(got) != len(want):
            return [f"{where}: {len(got)} items, pinned {len(want)}"]
        return [d for i, (g, w) in enumerate(zip(got, want, strict=True))
                for d in differences(g, w, f"{where}[{i}]")]  # fmt: skip
    if isinstance(want, float) and isinstance(got, int | float):
        if math.isnan(want) and math.isnan(got):
            return []
        if math.isclose(got, want, rel_tol=1e-12, abs_tol=1e-12):
            return []
    elif got == want:
        return []
    return [f"{where}: {got!r}, pinned {want!r}"]


def compute(short_only: bool, workers: int, engine: str, old: Mapping[str, Any]) -> dict[str, Any]:
    pinned: dict[str, Any] = {
        "about": "written by bench/pin_kpis.py; checked by tests/twin/test_pinned_kpis.py",
        "short": {"settings": {**SHORT, "seed": SHORT_SEED, "engine": "simpy"}, "runs": []},
    }
    for run in short_runs():
        kpis = short_kpis(run["scenario"], run["policy"])
        pinned["short"]["runs"].append({**run, "kpis": kpis})
        print(f"short {run['scenario']} {run['policy'] or '(own)'}: G {kpis['gripping_rate']:.4f}")
    if short_only:
        if "readme" in old:
            pinned["readme"] = old["readme"]
        return pinned
    ranking = rule_ranking()
    print("ranking:", {k: round(v, 3) for k, v in ranking.items()})
    calibration = {}
    for key, extra in (("calibrated", []), ("before", BEFORE)):
        calibration[key] = arm_sweep(extra, workers, engine)
        print(f"calibration {key}:", calibration[key])
    pinned["readme"] = {"ranking": ranking, "calibration": calibration}
    pinned["readme"]["text"] = readme_text(pinned["readme"])
    return pinned


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare with the pinned file only")
    ap.add_argument("--short", action="store_true", help="only the short runs (seconds)")
    ap.add_argument("--workers", type=int, default=2, help="workers of the two sweeps")
    ap.add_argument(
        "--engine", default="simpy", help="engine of the two sweeps (same results; fast is quicker)"
    )
    args = ap.parse_args()
    old = json.loads(PINNED.read_text()) if PINNED.is_file() else {}
    new = compute(args.short, args.workers, args.engine, old)
    failed = False
    if args.check:
        diffs = differences(new, old)
        for d in diffs:
            print("differs:", d)
        failed = bool(diffs)
    else:
        PINNED.parent.mkdir(parents=True, exist_ok=True)
        PINNED.write_text(json.dumps(new, indent=1, ensure_ascii=False) + "\n")
        print(f"wrote {PINNED.relative_to(ROOT)}")
    if "readme" in new:
        missing = readme_holds(new["readme"]["text"], README.read_text(encoding="utf-8"))
        for line in missing:
            print(f"README.md lacks: {line}")
        failed = failed or bool(missing)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
