"""The lookahead controller: one-step rollout over sampled futures, ``--policy lookahead``.

At each decision the controller tries each distinct part the rules (FIFO, LIFO, SD, LD,
SPT) would pick. For every candidate it plays the line forward for ``H`` seconds, the robots
then all following a base rule, under ``K`` sampled futures: the parts already on the belt
stay, later arrivals (and, with exponential breakdowns, the next failure of each robot and
the end of a repair under way) are redrawn from the run's own policy stream; every
candidate sees the same futures (common random numbers). It takes the candidate whose
continuations grip the most parts fed in [t - line transit, t + H), the base rule's pick on
ties. This is Bertsekas' one-step rollout with the base rule as the base policy; with a
truncated horizon and sampled futures it approximates the policy-improvement step rather than
guaranteeing it.

The continuations run on the compiled engine (:mod:`twin.fast`): the controller keeps its
own copy of the run, a :class:`~twin.fast.engine.FastLine` of the same scenario, seed and
duration whose every decision it answers as it answers the real line's, and plays all the
candidates x futures of a decision from that copy in one compiled call
(:func:`twin.fast.rollouts.continue_each`, as rollout labelling does; with exponential
breakdowns one call per future, each with its own redrawn failure times). The copy's events
are the real run's, whichever engine runs it, so the controller's choices, and the run, are
the same on the SimPy and the compiled engine; it checks the copy against every decision.
The line hands the controller its scenario and seed through ``bind_run`` (the twin calls it
on policies that have it, after ``reset``).

Settings live in the name: ``lookahead:K=32,H=1.5,base=SD``.

- ``K`` futures per decision (default 16);
- ``H`` horizon in seconds (default 1.0);
- ``base``: the rule the continuations follow and whose pick wins ties; ``auto`` (the
  default) is the better of SD and SPT on this line, measured on tuning seeds
  (:data:`TUNING_SEEDS`, disjoint from the evaluation seeds 0..N-1);
- ``oracle=1``: the clairvoyant variant, told the true future (the run's own arrivals and
  failure times: one future, the real one). It bounds what one-step lookahead with rule
  continuations can gain, not what every possible controller can.

:meth:`Lookahead.stats` reports the decisions, the ones planned (two or more distinct
candidates) and the CPU time per decision.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from pnp_twin.policies.base import RuleMix
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.errors import UserError, excerpt
from pnp_twin.twin.scenario import Scenario

if TYPE_CHECKING:
    from pnp_twin.twin.fast.engine import FastLine
    from pnp_twin.twin.fast.rollouts import Future

log = logging.getLogger(__name__)

TRIED: tuple[str, ...] = ("FIFO", "LIFO", "SD", "LD", "SPT")
"""The rules whose picks are the candidates (SIRO's pick is random, so it is left out)."""
BASES: tuple[str, ...] = ("SD", "SPT")
"""``base=auto`` takes the better of these on the line."""
TUNING_SEEDS: tuple[int, ...] = (700_000, 700_001, 700_002)
"""Seeds on which ``base=auto`` compares SD and SPT (evaluations use 0..N-1)."""
MAX_FUTURES = 4096
MAX_HORIZON = 600.0
MARGIN = 1.0
"""Seconds of future arrivals drawn past the end of a continuation."""


class LookaheadError(UserError):
    """A malformed ``lookahead:`` name; one line."""


@dataclass(frozen=True)
class LookaheadSettings:
    """What one lookahead controller does (parsed from its name by :func:`parse`)."""

    futures: int = 16
    """K: sampled futures per decision."""
    horizon: float = 1.0
    """H: parts fed up to this long after the decision count, s."""
    base: str = "auto"
    """The continuation rule: SD, SPT, FIFO, LIFO, LD, or auto (the better of SD and SPT)."""
    oracle: bool = False
    """Told the true future instead of sampling futures (the clairvoyant bound)."""

    @property
    def name(self) -> str:
        """The canonical policy name: ``lookahead:K=16,H=1,base=auto``."""
        if self.oracle:
            return f"lookahead:H={self.horizon:g},base={self.base},oracle=1"
        return f"lookahead:K={self.futures},H={self.horizon:g},base={self.base}"


_KEYS = {"k": "futures", "futures": "futures", "h": "horizon", "horizon": "horizon"}
_KEYS |= {"base": "base", "oracle": "oracle"}
_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def parse(arg: str) -> LookaheadSettings:
    """Settings from the text after ``lookahead:`` (``K=32,H=1.5,base=SD``; empty: defaults).

    Raises :class:`LookaheadError` naming the bad item and what is allowed."""
    values: dict[str, Any] = {}
    for item in (x.strip() for x in arg.split(",")):
        if not item:
            continue
        key, sep, value = (p.strip() for p in item.partition("="))
        field = _KEYS.get(key.lower())
        if not sep or field is None or not value:
            raise LookaheadError(
                f"policy: lookahead: {excerpt(item)} is not a setting; give K=FUTURES, "
                "H=SECONDS, base=RULE|auto or oracle=1, e.g. lookahead:K=32,H=1.5,base=SD"
            )
        if field in values:
            raise LookaheadError(f"policy: lookahead: {key} is given twice")
        values[field] = _value(field, key, value)
    return LookaheadSettings(**values)


def _value(field: str, key: str, text: str) -> Any:
    bad = f"policy: lookahead: {key}={excerpt(text)} is not allowed; "
    if field == "futures":
        if not (text.isascii() and text.isdigit()) or not 1 <= int(text) <= MAX_FUTURES:
            raise LookaheadError(bad + f"K is a whole number of futures, 1 to {MAX_FUTURES}")
        return int(text)
    if field == "horizon":
        try:
            h = float(text)
        except ValueError:
            h = math.nan
        if not 0.0 < h <= MAX_HORIZON:  # NaN fails too
            raise LookaheadError(
                bad + f"H is a horizon in seconds, > 0 and at most {MAX_HORIZON:g}"
            )
        return h
    if field == "base":
        rule = text.upper()
        if rule == "AUTO":
            return "auto"
        if rule not in TRIED:
            raise LookaheadError(bad + f"base is one of {', '.join(TRIED)} or auto")
        return rule
    if text.lower() in _TRUE:
        return True
    if text.lower() in _FALSE:
        return False
    raise LookaheadError(bad + "oracle is 1 or 0")


@functools.lru_cache(maxsize=64)
def _better_base(scenario_json: str, source_dir: str | None) -> str:
    from pnp_twin.twin.run import simulate

    scenario = Scenario.model_validate_json(scenario_json).located(source_dir)
    mean = {
        rule: float(
            np.mean(
                [
                    simulate(scenario, RuleMix([rule]), seed=s, engine="fast").kpis["gripping_rate"]
                    for s in TUNING_SEEDS
                ]
            )
        )
        for rule in BASES
    }
    best = max(BASES, key=lambda r: (mean[r], -BASES.index(r)))  # SD on a tie
    log.info("lookahead base=auto on %s: %s (%s)", scenario.name, best, mean)
    return best


def better_base(scenario: Scenario) -> str:
    """The better of SD and SPT on ``scenario`` (mean G over :data:`TUNING_SEEDS`, on the
    compiled engine; SD on a tie). Cached per scenario in the process."""
    return _better_base(scenario.model_dump_json(), scenario.source_dir)


class _Answer:
    """The copy's policy: the kernel stops at every decision; the controller answers."""

    name = "lookahead-copy"

    def __init__(self) -> None:
        self.k = 0
        self.last_rule: str | None = None

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        pass

    def choose(self, decision: Decision) -> int:
        return self.k


class Lookahead:
    """The lookahead controller (see the module docstring); a policy like any other."""

    def __init__(self, settings: LookaheadSettings | None = None) -> None:
        self.settings = settings or LookaheadSettings()
        self.name = self.settings.name
        self.last_rule: str | None = None
        self.rng = np.random.default_rng(0)
        self._run: tuple[Scenario, int, float] | None = None
        self._belt: Any = None
        self._copy: FastLine | None = None
        self._answer = _Answer()
        self.base = "SD"
        self.decisions = 0
        self.planned = 0
        self.cpu = 0.0

    # -- the policy protocol ---------------------------------------------------------------
    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.rng = rng  # the run's policy stream: the futures are drawn from it
        self._copy = None
        self.last_rule = None
        self.decisions, self.planned, self.cpu = 0, 0, 0.0

    def bind_run(self, scenario: Scenario, seed: int, duration: float) -> None:
        """The run this controller decides for (called by the line after ``reset``)."""
        if scenario.outfeed is not None:
            raise LookaheadError(
                "outfeed: the lookahead's rollouts run lines with bins only; use a rule "
                "(e.g. SPT) on a line with an outfeed"
            )
        self._run = (scenario, int(seed), float(duration))
        self._copy = None

    def attach(self, belt: Any) -> None:
        self._belt = belt

    def choose(self, decision: Decision) -> int:
        if self._copy is None:  # once per run, not counted per decision (base=auto's runs)
            self._copy = self._start()
        t0 = time.process_time()
        line = self._follow(decision)
        picks, _, _, k = self.plan(decision, line)
        self.last_rule = (
            self.base if k == picks[self.base] else next(r for r in TRIED if picks[r] == k)
        )
        self._answer.k, self._answer.last_rule = k, self.last_rule
        line.answer()
        self.decisions += 1
        self.cpu += time.process_time() - t0
        return k

    def plan(
        self, decision: Decision, line: Any
    ) -> tuple[dict[str, int], list[int], list[int] | None, int]:
        """One decision's plan: each tried rule's pick, the distinct candidates (the base
        rule's first), their totals over the futures from ``line`` (None when there is one
        candidate: nothing to plan) and the candidate taken (the most parts, the base
        rule's pick on ties)."""
        picks = {rule: RULES[rule](decision, self.rng) for rule in TRIED}
        candidates = list(dict.fromkeys([picks[self.base], *picks.values()]))
        if len(candidates) == 1:
            return picks, candidates, None, candidates[0]
        totals = self.values(line, candidates)
        self.planned += 1
        k = candidates[max(range(len(candidates)), key=lambda i: (totals[i], -i))]
        return picks, candidates, totals, k

    def stats(self) -> dict[str, Any]:
        """Decisions, planned decisions (two or more candidates), CPU seconds and ms per
        decision of the last run."""
        per = 1000.0 * self.cpu / self.decisions if self.decisions else math.nan
        return {
            "policy": self.name,
            "base": self.base,
            "decisions": self.decisions,
            "planned": self.planned,
            "cpu_s": self.cpu,
            "cpu_ms_per_decision": per,
        }

    # -- the copy of the run ---------------------------------------------------------------
    def _follow(self, decision: Decision) -> FastLine:
        """The copy, advanced to this decision (started at the run's first), checked."""
        from pnp_twin.twin.fast import layout as L

        line = self._copy
        assert line is not None
        status = line.advance(line.end_at)
        same = status == L.ST_CHOOSE and (
            int(line.gs[L.DROBOT]) == decision.robot
            and line.now == decision.time
            and int(line.gs[L.DN]) == len(decision.parts)
        )
        if not same:
            raise RuntimeError(
                f"lookahead: its copy of the run is not at the line's decision ({decision!r}, "
                f"copy at t={line.now:.4f}, status {status}); the line must be the scenario's "
                "own run (bind_run), driven by this policy alone"
            )
        return line

    def _start(self) -> FastLine:
        from pnp_twin.twin.fast.engine import FastLine

        if self._run is None:
            raise RuntimeError(
                "lookahead: the line did not bind its run (bind_run); run it with "
                "twin.run.simulate or a Line / FastLine"
            )
        scenario, seed, duration = self._run
        s = self.settings
        self.base = better_base(scenario) if s.base == "auto" else s.base
        line = FastLine(scenario, self._answer, seed=seed, duration=duration)
        line.start(0, 0, 64)  # no span buffer (nothing reads the copy's spans); streams grow
        if self._belt is not None and not _same_stream(self._belt, line):
            raise RuntimeError(
                "lookahead: the line's part stream is not its scenario's own; the lookahead "
                "controller runs only on the scenario's own stream"
            )
        self._transit = line.last_end / scenario.belt.speed
        self._sampler = FutureSampler(scenario, self.rng)
        self._failing = [
            r
            for r in range(scenario.robots.count)
            if scenario.robot_param(r + 1, "mtbf") > 0
            and scenario.robots.failure_distribution == "exponential"
        ]
        self._means = [
            (scenario.robot_param(r + 1, "mtbf"), scenario.robot_param(r + 1, "mttr"))
            for r in range(scenario.robots.count)
        ]
        return line

    # -- the rollouts ----------------------------------------------------------------------
    def values(self, line: FastLine, candidates: list[int]) -> list[int]:
        """Parts gripped (fed in [t - transit, t + H)) summed over the futures, for each
        candidate index, from ``line`` stopped at the decision."""
        from pnp_twin.twin.fast.rollouts import continue_each

        t = line.now
        lo, hi = t - self._transit, t + self.settings.horizon
        stop = min(line.end_at, hi + self._transit)
        n_kept = int(np.searchsorted(line.fed, t, "right"))
        futures = self.futures(line, n_kept, stop + MARGIN)
        rule = self.base
        if self.settings.oracle or not self._failing:
            totals = continue_each(line, futures, n_kept, candidates, rule, stop, (lo, hi))
            if totals is None:
                raise RuntimeError("lookahead: a continuation ran out of a pre-drawn stream")
            return totals
        out = [0] * len(candidates)
        for future in futures:  # failures redrawn per future: one compiled call each
            saved = line.fs.copy()
            try:
                self._redraw_failures(line)
                got = continue_each(line, [future], n_kept, candidates, rule, stop, (lo, hi))
            finally:
                line.fs[:] = saved
            if got is None:
                raise RuntimeError("lookahead: a continuation ran out of a pre-drawn stream")
            out = [a + b for a, b in zip(out, got, strict=True)]
        return out

    def futures(self, line: FastLine, n_kept: int, until: float) -> list[Future]:
        """The futures of a decision: the first ``n_kept`` parts are the run's own, later
        ones drawn up to ``until`` (the oracle: the run's own stream, one future); on a
        line with kinds of part, each with its parts' kind codes."""
        kinds = self._sampler.kinds is not None
        if self.settings.oracle:
            m = int(np.searchsorted(line.fed, until, "right"))
            if kinds:
                return [(line.fed[:m], line.y[:m], line.kind_code[:m])]
            return [(line.fed[:m], line.y[:m])]
        times, ys, counts = self._sampler.draw(
            line.now, until, self.settings.futures, line.fed, line.y, n_kept
        )
        k, width = times.shape
        feds = np.empty((k, n_kept + width))
        lat = np.empty((k, n_kept + width))
        feds[:, :n_kept] = line.fed[:n_kept]
        lat[:, :n_kept] = line.y[:n_kept]
        feds[:, n_kept:] = times
        lat[:, n_kept:] = ys
        if not kinds:
            return [(feds[m, : n_kept + c], lat[m, : n_kept + c]) for m, c in enumerate(counts)]
        codes = np.empty((k, n_kept + width), dtype=np.int64)
        codes[:, :n_kept] = line.kind_code[:n_kept]
        codes[:, n_kept:] = self._sampler.draw_kinds(times.shape, line.kind_code[:n_kept])
        return [
            (feds[m, : n_kept + c], lat[m, : n_kept + c], codes[m, : n_kept + c])
            for m, c in enumerate(counts)
        ]

    def _redraw_failures(self, line: FastLine) -> None:
        """Exponential breakdowns are memoryless: the next failure of a working robot and
        the end of a repair under way are redrawn from now."""
        from pnp_twin.twin.fast import layout as L

        now = line.now
        for r in self._failing:
            mtbf, mttr = self._means[r]
            if line.ist[r, L.DOWN]:
                line.fs[r, L.WAKE] = now + mttr * self.rng.standard_exponential()
            else:
                line.fs[r, L.NEXTFAIL] = now + mtbf * self.rng.standard_exponential()


def _same_stream(belt: Any, line: FastLine) -> bool:
    fed = np.asarray(belt.fed, dtype=float)
    return len(fed) == len(line.fed) and bool(np.array_equal(fed, line.fed))


class FutureSampler:
    """Arrivals after ``t`` and their lateral positions, drawn as the scenario's feeder
    draws them: Poisson (memoryless: from t), normal gaps (the first gap from the last
    arrival, conditioned on reaching past t), fixed spacing (the true times, positions
    redrawn) or a replayed trace (gaps and positions resampled from the parts seen so far).
    """

    def __init__(self, scenario: Scenario, rng: np.random.Generator) -> None:
        self.c = scenario.feeder
        self.width = scenario.belt.width
        self.rng = rng
        kinds = scenario.feeder.kinds  # None: one kind (no draws, as before kinds existed)
        self.kinds = np.cumsum([k.share for k in kinds]) if kinds else None

    def draw_kinds(self, shape: tuple[int, ...], seen: np.ndarray) -> np.ndarray:
        """Kind codes of drawn arrivals: by share, as the feeder draws them (a replayed
        trace: resampled from the kinds seen so far)."""
        assert self.kinds is not None
        if self.c.arrival == "trace":
            if len(seen) == 0:
                return np.zeros(shape, dtype=np.int64)
            return self.rng.choice(seen, size=shape)
        codes = np.searchsorted(self.kinds / self.kinds[-1], self.rng.random(shape), "right")
        return np.minimum(codes, len(self.kinds) - 1)

    def draw(
        self, t: float, until: float, k: int, fed: np.ndarray, ys: np.ndarray, n_kept: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times, ys, counts): ``k`` rows of arrivals in (t, until], padded with inf;
        ``counts[m]`` the arrivals of row m."""
        c = self.c
        if c.arrival == "fixed":
            true = fed[n_kept : int(np.searchsorted(fed, until, "right"))]
            times = np.broadcast_to(true, (k, len(true))).copy()
        elif c.arrival == "trace":
            times = self._resampled_gaps(t, until, k, fed[:n_kept])
        else:
            times = self._renewal(t, until, k, fed[:n_kept])
        times[times > until] = math.inf
        counts = np.isfinite(times).sum(axis=1)
        width = int(counts.max()) if k else 0
        times = times[:, :width]
        if c.arrival == "trace" and n_kept >= 2:
            lateral = self.rng.choice(ys[:n_kept], size=times.shape)
        else:
            lateral = self._lateral(times.shape)
        return times, lateral, counts

    def _renewal(self, t: float, until: float, k: int, seen: np.ndarray) -> np.ndarray:
        c, rng = self.c, self.rng
        mean = 1.0 / c.rate
        if c.arrival == "poisson":  # memoryless: the future starts now
            origin = np.full(k, t)
            first = rng.exponential(mean, k)
        else:  # normal gaps: from the last arrival, the first gap reaching past t
            last = float(seen[-1]) if len(seen) else 0.0
            origin = np.full(k, last)
            first = np.maximum(rng.normal(mean, c.cv * mean, k), 0.0)
            for _ in range(64):
                short = last + first <= t
                if not short.any():
                    break
                first[short] = np.maximum(rng.normal(mean, c.cv * mean, int(short.sum())), 0.0)
            short = last + first <= t
            origin[short] = t  # out of luck: the next gap from now
        n = max(int((until - t) / mean * 1.5) + 8, 8)
        while True:
            if c.arrival == "poisson":
                gaps = rng.exponential(mean, (k, n - 1))
            else:
                gaps = np.maximum(rng.normal(mean, c.cv * mean, (k, n - 1)), 0.0)
            times = origin[:, None] + np.cumsum(np.column_stack([first, gaps]), axis=1)
            if k == 0 or times[:, -1].min() > until:
                return times
            n *= 2  # a row fell short of ``until``: draw the rows again, longer

    def _resampled_gaps(self, t: float, until: float, k: int, seen: np.ndarray) -> np.ndarray:
        if len(seen) < 2:  # nothing to resample from yet: an empty future
            return np.full((k, 1), math.inf)
        gaps = np.diff(seen[-1000:])
        mean = max(float(gaps.mean()), 1e-9)
        n = max(int((until - t) / mean * 1.5) + 8, 8)
        while True:
            drawn = self.rng.choice(gaps, size=(k, n))
            times = t + np.cumsum(drawn, axis=1)
            if k == 0 or times[:, -1].min() > until or n > 1_000_000:
                return times
            n *= 2

    def _lateral(self, shape: tuple[int, ...]) -> np.ndarray:
        c, rng, w = self.c, self.rng, self.width
        if c.lateral == "uniform":
            return rng.uniform(0.0, w, shape)
        mean = w / 2.0 if c.lateral_mean is None else c.lateral_mean
        out = rng.normal(mean, c.lateral_sd, shape)
        bad = (out < 0.0) | (out > w)
        while bad.any():  # truncated normal by rejection, as the feeder draws it
            out[bad] = rng.normal(mean, c.lateral_sd, int(bad.sum()))
            bad = (out < 0.0) | (out > w)
        return out


def from_spec(arg: str) -> Lookahead:
    """``lookahead:K=32,H=1.5,base=SD`` (``lookahead`` alone: the defaults)."""
    return Lookahead(parse(arg))
