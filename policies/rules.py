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
    """Shortest distance: the part nearest the upper edge (the bin side)."""
    ys = d.ys
    return ys.index(max(ys))


def ld(d: Decision, rng: np.random.Generator) -> int:
    """Longest distance: the part nearest the lower edge."""
    ys = d.ys
    return ys.index(min(ys))


def cycle_times(d: Decision) -> list[float]:
    """Full cycle time per candidate: approach + grip + move to the bin + release."""
    s = d.spec
    bx, by = s.bin
    out = []
    for x, y, t in zip(d.xs, d.ys, d.times, strict=True):
        xi = x + s.belt_speed * t
        transfer = move_time(((bx - xi) ** 2 + (by - y) ** 2) ** 0.5, s.arm_speed, s.acceleration)
        out.append(t + s.pick_time + transfer + s.place_time)
    return out


def spt(d: Decision, rng: np.random.Generator) -> int:
    """Shortest processing time: the smallest full cycle time (Huang et al. 2015)."""
    c = cycle_times(d)
    return c.index(min(c))


RULES: dict[str, Rule] = {"FIFO": fifo, "LIFO": lifo, "SIRO": siro, "SD": sd, "LD": ld, "SPT": spt}
"""The paper's five rules (the meta-controller's actions, in this order) plus SPT."""

PAPER_RULES: tuple[str, ...] = ("FIFO", "LIFO", "SIRO", "SD", "LD")
