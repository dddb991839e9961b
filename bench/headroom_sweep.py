"""Where does coordination start to matter? ``pnp-twin headroom`` over workspace length and
grip/release time on ``paper_baseline``, one table.

    python bench/headroom_sweep.py [--seeds 5] [--duration 300] [--out out/headroom_sweep]

Each point is one ``pnp-twin headroom paper_baseline --set robots.workspace_length=L --set
robots.pick_time=G --set robots.place_time=G`` (held-out seeds 0..N-1, common random numbers,
paired 95 % intervals against the point's best rule); the static mix is fixed to the
baseline's best (``--mix SD,SPT,SD,SD``) to keep the sweep short. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

LENGTHS = (0.22, 0.35, 0.5)  # m: the calibrated line's, and longer workspaces
GRIPS = (0.0037, 0.06)  # s: the calibrated grip/release, and a slower gripper


def headroom(length: float, grip: float, args: argparse.Namespace) -> dict:
    out = Path(args.out) / f"ws{length}_grip{grip}"
    cli = [sys.executable, "-m", "pnp_twin", "headroom", "paper_baseline", "--json"]
    cli += ["--seeds", str(args.seeds), "--duration", str(args.duration), "--mix", "SD,SPT,SD,SD"]
    cli += ["--set", f"robots.workspace_length={length}"]
    cli += ["--set", f"robots.pick_time={grip}", "--set", f"robots.place_time={grip}"]
    cli += ["--workers", str(args.workers), "--out", str(out)]
    done = subprocess.run(cli, capture_output=True, text=True, check=True)
    return json.loads(done.stdout)


def cell(entry: dict) -> str:
    return f"{entry['gain']:+.2f} [{entry['gain_ci_low']:+.2f}, {entry['gain_ci_high']:+.2f}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--duration", type=float, default=300.0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default="out/headroom_sweep")
    args = parser.parse_args()
    print(f"paper_baseline, seeds 0-{args.seeds - 1}, {args.duration:g} s runs; gains in points")
    print("| workspace length | grip = release | best rule, G % | lookahead | bound |")
    print("| --- | --- | --- | --- | --- |")
    for length in LENGTHS:
        for grip in GRIPS:
            r = headroom(length, grip, args)
            best = r["best_rule"]
            print(
                f"| {length} m | {grip} s | {best['policy']} {best['gripping_rate']:.2f} | "
                f"{cell(r['lookahead'])} | {cell(r['bound'])} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
