"""Flush the subnormal floats of the shipped models, showing the decisions do not change.

    python bench/flush_models.py [--write] [--duration 60] [--pin FILE]

For each model in ``models/``: counts its subnormal weights, runs ``paper_baseline`` (seed 0,
``--duration`` simulated s, the fast engine) with the weights as stored (not flushed) and
flushed, and checks that both runs took the same decisions (robot, part, rule, grip time of
every part). ``--write`` then rewrites ``model.safetensors`` flushed; ``--pin FILE`` writes
each model's decision digest of the run as stored, which
``tests/learning/test_subnormals.py`` checks the flushed models against.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import pandas as pd
from safetensors.torch import save

from pnp_twin.policies.hdqn.agent import QAgent
from pnp_twin.policies.hdqn.checkpoint import (
    MODEL,
    count_subnormals,
    flush_subnormals,
    load_agent,
    load_into,
    read_tensors,
    shipped_models,
)
from pnp_twin.policies.hdqn.policy import HDQNPolicy
from pnp_twin.twin import load_scenario, with_overrides
from pnp_twin.twin.run import simulate

MODELS = Path(__file__).resolve().parents[1] / "models"


def decisions(policy: HDQNPolicy, duration: float) -> pd.DataFrame:
    """The parts table of a ``paper_baseline`` run (seed 0): who picked what, by which rule."""
    scenario = with_overrides(
        load_scenario("paper_baseline"), {"duration": duration, "warmup": 10.0}
    )
    result = simulate(scenario, policy, seed=0, engine="fast")
    return result.parts[["part", "robot", "rule", "picked_at"]].reset_index(drop=True)


def digest(parts: pd.DataFrame) -> str:
    return hashlib.sha256(parts.to_csv(index=False).encode()).hexdigest()[:16]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="rewrite the shipped files flushed")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--pin", type=Path, default=None)
    args = ap.parse_args()
    pins = {}
    for name in shipped_models():
        path = MODELS / name
        tensors = read_tensors(path / MODEL)
        n = sum(v.numel() for v in tensors.values() if v.is_floating_point())
        sub = count_subnormals(tensors)
        raw_agent, meta = load_into(QAgent, path, flush=False)
        flushed_agent, _ = load_agent(path)
        raw = decisions(HDQNPolicy(raw_agent, meta), args.duration)
        flushed = decisions(HDQNPolicy(flushed_agent, meta), args.duration)
        same = raw.equals(flushed)
        pins[name] = {"duration": args.duration, "decisions": digest(raw), "parts": len(raw)}
        print(
            f"{name:32s} {sub:6d} of {n:6d} weights subnormal ({sub / n:5.1%}); "
            f"{len(raw)} parts, decisions {'identical' if same else 'DIFFER'} after the flush"
        )
        if not same:
            raise SystemExit(f"{name}: flushing changed the decisions; not writing")
        if args.write and sub:
            (path / MODEL).write_bytes(save(flush_subnormals(tensors)))
    if args.pin is not None:
        args.pin.write_text(json.dumps(pins, indent=2, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
