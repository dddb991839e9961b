"""Dispatching rules: tiny functions from a decision to the index of the part to pick.

Candidates arrive furthest downstream first, i.e. in the order they entered the workspace.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pnp_twin.twin.decision import Decision
from pnp_twin.twin.geometry import move_time

Rule = Callable[[Decision, np.random.Generator], int]


def fifo(d: Decision, rng: np.random.Generator) -> int:
    """First in, first out: the part that entered the workspace first (furthest downstream)."""
    return 0


def lifo(d: Decision, rng: np.random.Generator) -> int:
    """Last in, first out: the part that entered last (furthest upstream)."""
    return len(d.parts) - 1


def siro(d: Decision, rng: np.random.Generator) -> int:
    """Service in random order: uniformly random, from the run's seeded policy stream."""
    return int(rng.integers(len(d.parts)))


def sd(d: Decision, rng: np.random.Generator) -> int:
    """Shortest distance: the part nearest the belt edge on the bin's side (the upper edge
    for a robot on the upper side, the lower edge for one on the lower side)."""
    ys = d.ys
    return ys.index(max(ys) if d.spec.bin_side > 0 else min(ys))


def ld(d: Decision, rng: np.random.Generator) -> int:
    """Longest distance: the part nearest the edge away from the bin."""
    ys = d.ys
    return ys.index(min(ys) if d.spec.bin_side > 0 else max(ys))


def cycle_times(d: Decision) -> list[float]:
    """Full cycle time per candidate: approach + grip + move to the bin + release (the grip
    and release times of each candidate's kind)."""
    s = d.spec
    bx, by = s.bin
    out = []
    for x, y, t, kind in zip(d.xs, d.ys, d.times, d.kinds, strict=True):
        xi = x + s.belt_speed * t
        transfer = move_time(((bx - xi) ** 2 + (by - y) ** 2) ** 0.5, s.arm_speed, s.acceleration)
        out.append(t + s.pick_of(kind) + transfer + s.place_of(kind))
    return out


def spt(d: Decision, rng: np.random.Generator) -> int:
    """Shortest processing time: the smallest full cycle time (Huang et al. 2015)."""
    c = cycle_times(d)
    return c.index(min(c))


def val(d: Decision, rng: np.random.Generator) -> int:
    """Highest value first (feeder.kinds' value), the shortest processing time among equals."""
    values = [d.spec.value_of(k) for k in d.kinds]
    top = max(values)
    c = cycle_times(d)
    return min((i for i, v in enumerate(values) if v == top), key=lambda i: c[i])


RULES: dict[str, Rule] = {"FIFO": fifo, "LIFO": lifo, "SIRO": siro, "SD": sd, "LD": ld, "SPT": spt}
"""The paper's five rules (the meta-controller's actions, in this order) plus SPT: the rules
studies compare and learners choose among by default."""

NAMED_RULES: dict[str, Rule] = {**RULES, "VAL": val}
"""Every rule a policy name may use: :data:`RULES` and VAL, which only means something on a
line whose kinds of part have different values."""

PAPER_RULES: tuple[str, ...] = ("FIFO", "LIFO", "SIRO", "SD", "LD")
