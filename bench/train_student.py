"""Train the HDQN on the lookahead controller's values: the planner teaches, the network acts.

    python bench/train_student.py --name NAME [--line SCENARIO [--set path=value ...]] ...
        [--teacher lookahead:K=16,H=1,base=auto] [--runs 8] [--duration 120] [--dagger 1]
        [--beta 0.3] [--epochs 40] [--workers 2] [--out runs/student]

Each ``--line`` starts a line of the training set (a scenario name or file); the ``--set``
options after it override its fields, as ``pnp-twin run --set`` does. With several lines the
network learns across them (its decision features include each robot's arm speed, the belt
speed and the feeder's rate). For each line, ``--runs`` runs of ``--duration`` s are labelled
by the teacher (seeds 3,000,000 + ...: disjoint from evaluation seeds), the last tenth held
out; then ``--dagger`` rounds in which the student acts (the teacher with probability
``--beta``) and the teacher labels the states it visits. The checkpoint goes to
``OUT/NAME`` (``meta.json``, ``model.safetensors``, the label files, ``agreement.csv``: per
round the labels, the held-out agreement with the teacher and the regret in parts per
future); use it as ``--policy hdqn:OUT/NAME``. ``--ship DIR`` then copies what inference
needs (``meta.json`` named after DIR's last part, ``model.safetensors``, ``agreement.csv``;
not the label files) into DIR (``--ship-only``: without training again), e.g. ``--ship
models/paper_baseline__student``; a rerun with the same ``--out``/``--name`` reuses the label
files it finds (and fits again).
See :mod:`pnp_twin.learning.student`.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
from pathlib import Path

from pnp_twin.learning.student import LineSpec, StudentArgs, train_student
from pnp_twin.policies.hdqn.features import SETS


def lines(argv: list[str]) -> tuple[list[LineSpec], list[str]]:
    """Pull ``--line X [--set a=b ...]`` groups out of argv; the rest goes to argparse."""
    out: list[LineSpec] = []
    rest: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] == "--line":
            out.append(LineSpec(argv[i + 1]))
            i += 2
        elif argv[i] == "--set":
            if not out:
                raise SystemExit("--set comes after the --line it changes")
            last = out[-1]
            out[-1] = LineSpec(last.scenario, (*last.sets, argv[i + 1]))
            i += 2
        else:
            rest.append(argv[i])
            i += 1
    return out or [LineSpec()], rest


def main(argv: list[str] | None = None) -> None:
    import sys

    specs, rest = lines(list(sys.argv[1:] if argv is None else argv))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    d = StudentArgs()
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", default=d.out)
    ap.add_argument("--teacher", default=d.teacher)
    ap.add_argument("--seed", type=int, default=d.seed)
    ap.add_argument("--runs", type=int, default=d.runs)
    ap.add_argument("--duration", type=float, default=d.duration)
    ap.add_argument("--dagger", type=int, default=d.dagger)
    ap.add_argument("--beta", type=float, default=d.beta)
    ap.add_argument("--epochs", type=int, default=d.epochs)
    ap.add_argument("--lr", type=float, default=d.lr)
    ap.add_argument("--floor", type=float, default=d.floor)
    ap.add_argument("--workers", type=int, default=d.workers)
    ap.add_argument("--view", choices=("none", "window", "belt"), default=d.view)
    ap.add_argument("--features", choices=SETS, default=d.features)
    ap.add_argument("--network", default=d.network)
    ap.add_argument(
        "--also",
        action="append",
        default=[],
        help="an earlier training's folder: its labels join the fit",
    )
    ap.add_argument("--ship", type=Path, default=None)
    ap.add_argument("--ship-only", action="store_true", help="copy OUT/NAME, train nothing")
    a = ap.parse_args(rest)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    args = StudentArgs(
        lines=specs,
        out=a.out,
        name=a.name,
        teacher=a.teacher,
        seed=a.seed,
        runs=a.runs,
        duration=a.duration,
        dagger=a.dagger,
        beta=a.beta,
        epochs=a.epochs,
        lr=a.lr,
        floor=a.floor,
        workers=a.workers,
        view=a.view,
        features=a.features,
        network=a.network,
        also=a.also,
    )
    if a.ship_only:
        if a.ship is None:
            raise SystemExit("--ship-only needs --ship DIR")
        ship(Path(a.out) / a.name, a.ship)
        print("shipped to", a.ship)
        return
    folder = train_student(args)
    print(folder)
    print((folder / "agreement.csv").read_text(encoding="utf-8"), end="")
    if a.ship is not None:
        ship(folder, a.ship)
        print("shipped to", a.ship)


def ship(folder: Path, target: Path) -> None:
    """Copy a trained student's inference files into ``target`` (named after it)."""
    target.mkdir(parents=True, exist_ok=True)
    meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    meta["name"] = target.name
    text = json.dumps(meta, indent=2, sort_keys=True) + "\n"
    (target / "meta.json").write_text(text, encoding="utf-8")
    for name in ("model.safetensors", "agreement.csv"):
        shutil.copyfile(folder / name, target / name)


if __name__ == "__main__":
    main()
