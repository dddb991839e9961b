"""The feeder: the stream of parts put on the belt at x = 0.

Part positions are analytic (x = v_b (t - fed_at)), so feeding a part needs no event: the
feeder draws its whole arrival stream when the run starts, from its own random streams.
Every policy therefore sees exactly the same parts for the same seed (common random
numbers), and the stream costs no simulation events.
"""

from __future__ import annotations

import csv
import logging
from pathlib import Path

import numpy as np

from twin.errors import UserError
from twin.scenario import FeederConfig

log = logging.getLogger(__name__)


class TraceError(UserError):
    """A trace file that cannot be replayed; the message is one line."""


class Feeder:
    """Draws arrival times and lateral positions for one run."""

    def __init__(
        self,
        config: FeederConfig,
        belt_width: float,
        arrivals_rng: np.random.Generator,
        lateral_rng: np.random.Generator,
        source_dir: str | None = None,
    ) -> None:
        self.config = config
        self.width = belt_width
        self.arrivals_rng = arrivals_rng
        self.lateral_rng = lateral_rng
        self.source_dir = source_dir

    def stream(self, duration: float) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
        """(fed_at, y, kind or None) of every part fed in [0, duration), time-ordered."""
        c = self.config
        if c.arrival == "trace":
            return self._replay(duration)
        if c.arrival == "fixed":
            times = np.arange(0.0, duration, 1.0 / c.rate)
        else:
            times = self._gaps(duration)
        return times, self._lateral(len(times)), None

    def _gaps(self, duration: float) -> np.ndarray:
        c, rng = self.config, self.arrivals_rng
        mean = 1.0 / c.rate
        chunks: list[np.ndarray] = []
        t, batch = 0.0, max(int(duration * c.rate * 1.1) + 16, 64)
        while t < duration:
            if c.arrival == "poisson":
                gaps = rng.exponential(mean, batch)
            else:  # normal gaps, truncated at zero (parts cannot overtake)
                gaps = np.maximum(rng.normal(mean, c.cv * mean, batch), 0.0)
            times = t + np.cumsum(gaps)
            chunks.append(times)
            t = float(times[-1])
        times = np.concatenate(chunks)
        return times[times < duration]

    def _lateral(self, n: int) -> np.ndarray:
        c, rng, w = self.config, self.lateral_rng, self.width
        if c.lateral == "uniform":
            return rng.uniform(0.0, w, n)
        mean = w / 2.0 if c.lateral_mean is None else c.lateral_mean
        out = rng.normal(mean, c.lateral_sd, n)
        bad = (out < 0.0) | (out > w)
        while bad.any():  # truncated normal by rejection
            out[bad] = rng.normal(mean, c.lateral_sd, int(bad.sum()))
            bad = (out < 0.0) | (out > w)
        return out

    def _replay(self, duration: float) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
        path = Path(self.config.trace or "")
        if not path.is_absolute() and self.source_dir:
            path = Path(self.source_dir) / path
        times, ys, kinds = read_trace(path, self.width)
        keep = times < duration
        log.info("replaying %d of %d parts from %s", int(keep.sum()), len(times), path)
        kept_kinds = [k for k, ok in zip(kinds, keep, strict=True) if ok] if kinds else None
        return times[keep], ys[keep], kept_kinds


def read_trace(path: Path, width: float) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """Read a recorded trace CSV with columns time, y[, kind]."""
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as e:
        raise TraceError(f"feeder.trace: cannot read '{path}': {e.strerror}") from None
    if not rows or not {"time", "y"} <= set(rows[0]):
        raise TraceError(f"feeder.trace: '{path}' needs a header with columns time, y[, kind]")
    try:
        times = np.array([float(r["time"]) for r in rows])
        ys = np.array([float(r["y"]) for r in rows])
    except (TypeError, ValueError):
        raise TraceError(f"feeder.trace: '{path}' has a non-numeric time or y") from None
    if (np.diff(times) < 0).any() or (times < 0).any():
        raise TraceError(f"feeder.trace: '{path}' times must be >= 0 and non-decreasing")
    if ((ys < 0) | (ys > width)).any():
        raise TraceError(f"feeder.trace: '{path}' has y outside the belt (0..{width} m)")
    kinds = [r.get("kind") or "" for r in rows] if "kind" in rows[0] else None
    return times, ys, kinds


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
