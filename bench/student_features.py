"""Which decision features tell the teacher's choices apart? Fit on a training's labels, score
on its held-out runs.

    python bench/student_features.py FOLDER [FOLDER ...] [--epochs 40] [--seed 1]

FOLDER is a ``bench/train_student.py`` output whose labels were recorded with feature set
``student-v4`` (``labels_0.npz``, ``held_0.npz``; round 0 only, where the teacher acted).
On the held-out runs' rows it prints, for each way of choosing, the share of rows where the
choice picks the teacher's part (agreement) and the mean value it loses against the
teacher's pick, in parts gripped per future (regret; lower is better):

- the rules SPT and SD alone;
- each known-parts continuation alone (the pick with the most grips in it, SPT's on ties):
  the short one (a second) and the long one (until the parts have left the line);
- the student's network fitted on ``student-v2``'s columns (the first ones of ``student-v4``),
  on ``student-v3``'s (with the short continuation) and on all of ``student-v4``'s, with the
  same labels, epochs and seed.

The fits are those of :func:`pnp_twin.learning.student.fit` (one thread).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from pnp_twin.learning.student import (
    RULE_ORDER,
    StudentArgs,
    TeacherLabels,
    agreement,
    choice_scores,
    fit,
)
from pnp_twin.policies.hdqn.features import size

N_ROBOTS = 4


def columns(labels: TeacherLabels, cols: int) -> TeacherLabels:
    """The labels with no image and only the first ``cols`` features."""
    obs = np.zeros((len(labels), 0, 1, 1), np.uint8)
    return TeacherLabels(obs, labels.extra[:, :cols], labels.values, labels.mask, labels.line)


def show(choice: str, scores: dict[str, float]) -> None:
    print(f"{choice:<28} {scores['agreement']:>9.3f} {scores['regret']:>8.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    for f in a.folders:
        missing = [n for n in ("labels_0.npz", "held_0.npz") if not (f / n).is_file()]
        if missing:
            ap.error(f"{f}: no {' or '.join(missing)}; give a bench/train_student.py output")
    torch.set_num_threads(1)
    train = TeacherLabels.concat([TeacherLabels.load(f / "labels_0.npz") for f in a.folders])
    held = TeacherLabels.concat([TeacherLabels.load(f / "held_0.npz") for f in a.folders])
    n_rules = len(RULE_ORDER)
    widths = {n: size(n, n_rules, N_ROBOTS) for n in ("student-v2", "student-v3", "student-v4")}
    if train.extra.shape[1] != widths["student-v4"]:
        ap.error(
            f"the labels have {train.extra.shape[1]} features; student-v4 has "
            f"{widths['student-v4']} (train them with --features student-v4)"
        )
    print(f"{len(train)} training rows, {len(held)} held-out rows")
    print(f"{'choice':<28} {'agreement':>9} {'regret':>8}")
    for rule in ("SPT", "SD"):
        show(f"{rule} alone", choice_scores(held, np.full(len(held), RULE_ORDER.index(rule))))
    tails = held.extra[:, widths["student-v2"] :].reshape(len(held), 2, n_rules, -1)
    spt = RULE_ORDER.index("SPT")
    for t, name in enumerate(("short", "long")):
        shortfall = tails[:, t, :, 3]  # against the best pick's grips
        act = np.where(shortfall[:, spt] == 0.0, spt, shortfall.argmin(axis=1))
        show(f"{name} continuation alone", choice_scores(held, act))
    for name, cols in widths.items():
        args = StudentArgs(name=name, seed=a.seed, epochs=a.epochs, features=name)
        agent = fit(columns(train, cols), args, N_ROBOTS)
        show(f"network, {name}", agreement(agent, columns(held, cols)))


if __name__ == "__main__":
    main()
