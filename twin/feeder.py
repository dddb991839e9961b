"""The feeder: the stream of parts put on the belt at x = 0.

The feeder draws its whole arrival stream when the run starts, from its own random streams,
so every policy sees exactly the same parts for the same seed (common random numbers).
Its process :meth:`Feeder.feeding` then puts each part on the belt at its arrival time;
part positions on the belt are analytic (x = v_b (t - fed_at)).
"""

from __future__ import annotations

import logging
from collections.abc import Generator
from heapq import heappush
from typing import TYPE_CHECKING, Any

import numpy as np
import simpy
from simpy.events import URGENT

from pnp_twin.twin.plan import FIRST_ROBOT
from pnp_twin.twin.scenario import FeederConfig, Scenario
from pnp_twin.twin.trace import TraceError, read_trace, resolve, trace_paths  # noqa: F401  (TraceError kept importable)

if TYPE_CHECKING:
    from pnp_twin.twin.belt import Belt

log = logging.getLogger(__name__)

PartStream = tuple[np.ndarray, np.ndarray, "list[str] | None"]
"""(fed_at, y, kind or None) of every part of a run, time-ordered."""


class Feeder:
    """Draws arrival times and lateral positions for one run."""

    def __init__(
        self,
        config: FeederConfig,
        belt_width: float,
        arrivals_rng: np.random.Generator,
        lateral_rng: np.random.Generator,
        source_dir: str | None = None,
        kinds_rng: np.random.Generator | None = None,
    ) -> None:
        """``kinds_rng``: the stream the parts' kinds are drawn from (read only when
        ``config.kinds`` is given and no trace names them)."""
        self.config = config
        self.width = belt_width
        self.arrivals_rng = arrivals_rng
        self.lateral_rng = lateral_rng
        self.source_dir = source_dir
        self.kinds_rng = kinds_rng
        self.codes: np.ndarray | None = None  # the last drawn stream's kind codes

    def stream(self, duration: float) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
        """(fed_at, y, kind or None) of every part fed in [0, duration), time-ordered."""
        c = self.config
        if c.arrival == "trace":
            return self._replay(duration)
        if c.arrival == "fixed":
            times = np.arange(0.0, duration, 1.0 / c.rate)
        else:
            times = self._gaps(duration)
        return times, self._lateral(len(times)), self._kinds(len(times))

    @classmethod
    def seeded(cls, scenario: Scenario, seed: int) -> Feeder:
        """The feeder of a run of ``scenario`` with master ``seed`` (its first two child
        streams and the kinds' stream, as :class:`twin.plan.LinePlan` spawns them)."""
        kinds_stream = FIRST_ROBOT + scenario.robots.count  # LinePlan.kinds_stream
        seeds = np.random.SeedSequence(seed).spawn(kinds_stream + 1)
        arrivals, lateral, kinds = (np.random.default_rng(seeds[k]) for k in (0, 1, -1))
        width, where = scenario.belt.width, scenario.source_dir
        return cls(scenario.feeder, width, arrivals, lateral, where, kinds)

    def _kinds(self, n: int) -> list[str] | None:
        """Each part's kind, drawn by share (None on a line of one kind)."""
        kinds = self.config.kinds
        if not kinds:
            return None
        assert self.kinds_rng is not None, "a line with feeder.kinds needs the kinds' stream"
        edges = np.cumsum([k.share for k in kinds])
        codes = np.searchsorted(edges / edges[-1], self.kinds_rng.random(n), side="right")
        self.codes = np.minimum(codes, len(kinds) - 1)  # the kind codes, for the engines
        return np.array([k.name for k in kinds], dtype=object)[self.codes].tolist()

    def feeding(self, env: simpy.Environment, belt: Belt) -> Generator[simpy.Event, Any, None]:
        """The feeder's process: put each part of the belt's stream on it at its arrival.

        One process for the whole stream, sleeping until the next arrival. It wakes at the
        arrival instant exactly and ahead of any other event of that instant, so a robot
        that looks then sees the part.
        """
        fed = belt.fed
        i, n = 0, len(fed)
        while i < n:
            at = fed[i]
            if at > env.now:
                yield _Arrival(env, at)
            j = i + 1
            while j < n and fed[j] <= at:  # parts arriving together
                j += 1
            belt.arrived = j  # Belt.put, inlined: this loop runs once per part
            i = j

    def _gaps(self, duration: float) -> np.ndarray:
        c, rng = self.config, self.arrivals_rng
        mean = 1.0 / c.rate
        chunks: list[np.ndarray] = []
        t, batch = 0.0, max(int(duration * c.rate * 1.1) + 16, 64)
        while t < duration:
            if c.arrival == "poisson":  # exponential(mean, k), the same doubles, faster
                times = rng.standard_exponential(batch)
                times *= mean
            else:  # normal gaps, truncated at zero (parts cannot overtake)
                times = rng.normal(mean, c.cv * mean, batch)
                np.maximum(times, 0.0, out=times)
            np.cumsum(times, out=times)  # in place: one array per chunk, not four
            times += t  # t + each sum, as ever (x + 0.0 included: it turns -0.0 into 0.0)
            chunks.append(times)
            t = float(times[-1])
        times = chunks[0] if len(chunks) == 1 else np.concatenate(chunks)
        return times[: int(np.searchsorted(times, duration, "left"))]  # sorted: those < duration

    def _lateral(self, n: int) -> np.ndarray:
        c, rng, w = self.config, self.lateral_rng, self.width
        if c.lateral == "uniform":
            return rng.uniform(0.0, w, n)
        mean = w / 2.0 if c.lateral_mean is None else c.lateral_mean
        out = rng.standard_normal(n)  # normal(mean, sd, n): the same doubles (mean + sd * z)
        out *= c.lateral_sd
        out += mean
        bad = np.flatnonzero((out < 0.0) | (out > w))
        while len(bad):  # truncated normal by rejection: redraw the bad ones, in order
            again = rng.normal(mean, c.lateral_sd, len(bad))
            out[bad] = again
            bad = bad[(again < 0.0) | (again > w)]
        return out

    def _replay(self, duration: float) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
        path = trace_paths(self.config.trace or "", self.source_dir)[0]  # a run: the first
        times, ys, kinds = read_trace(path, self.width)
        keep = times < duration
        log.info("replaying %d of %d parts from %s", int(keep.sum()), len(times), path)
        kept_kinds = [k for k, ok in zip(kinds, keep, strict=True) if ok] if kinds else None
        return times[keep], ys[keep], kept_kinds


class _Arrival(simpy.Event):
    """A timeout that fires at the absolute time ``at``, ahead of every other event of that
    instant (URGENT priority); initialised as :class:`simpy.Timeout` initialises itself.

    ``Environment.schedule`` takes a delay, and ``now + (at - now)`` can miss ``at`` by a
    unit in the last place (with ties to even, some sums are out of reach), so it is queued
    at ``at`` itself, the way ``schedule`` queues events.
    """

    def __init__(self, env: simpy.Environment, at: float) -> None:
        self.env = env
        self.callbacks = []
        self._value = None
        self._ok = True
        heappush(env._queue, (at, URGENT, next(env._eid), self))


def resampled(scenario: Scenario, seed: int, other: int, at: float, duration: float) -> PartStream:
    """The stream of ``seed`` up to ``at``, then ``other``'s: a sampled future for rollouts
    (``Line(parts=...)``); both fed for ``duration`` s."""
    now = Feeder.seeded(scenario, seed).stream(duration)
    return splice(now, Feeder.seeded(scenario, other).stream(duration), at)


def splice(
    now: tuple[np.ndarray, np.ndarray, list[str] | None],
    then: tuple[np.ndarray, np.ndarray, list[str] | None],
    at: float,
) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """The stream ``now`` up to time ``at`` (inclusive), then ``then`` after it.

    A sampled future for rollouts: the parts already on the belt stay, the ones still to
    come are drawn again from another seed's stream.
    """
    (t0, y0, k0), (t1, y1, k1) = now, then
    keep0, keep1 = t0 <= at, t1 > at
    kind = None
    if k0 is not None and k1 is not None:
        kind = [k for k, keep in zip(k0, keep0, strict=True) if keep]
        kind += [k for k, keep in zip(k1, keep1, strict=True) if keep]
    return (
        np.concatenate([t0[keep0], t1[keep1]]),
        np.concatenate([y0[keep0], y1[keep1]]),
        kind,
    )
