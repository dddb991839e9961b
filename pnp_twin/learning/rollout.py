"""Rollout targets for the meta-controller: team picks per rule, over sampled futures.

The paper's reward (eq. 1, each robot's own pick rate) has the greedy per-robot rule, SPT,
as its optimum, and on a capacity-bound line a DQN trained on it ends up tied with SPT.
What the gripping rate counts is the team's picks, and the best rule for one robot depends
on what the others will do. This module measures that directly, as in rollout-based policy
iteration (Bertsekas' rollout; Lagoudakis and Parr's "RL as classification using rollouts"):

1. an *episode* runs the twin under t_continue with the base rule (SPT), choosing a random
   other rule with probability ``explore`` so that the states vary;
2. at each decision in the labelling window, for each distinct part the rules would pick,
   the run is replayed with that choice and then the base rule, over ``futures`` sampled
   futures (parts already on the belt stay, later arrivals are redrawn from other seeds:
   :func:`twin.feeder.resampled`, given to :class:`twin.line.Line` as ``parts=``), the
   same futures for every choice (common random numbers); the label of a rule is the mean
   number of parts fed in [t - line transit, t + horizon) that end up gripped;
3. the label rows are the deciding robot's observation (the whole belt image, parts and
   claimed parts) with its one-hot index, and the advantage of each rule over the base rule.

:mod:`pnp_twin.learning.rollout_train` fits the Q-network to these advantages. The labels of an
episode depend only on the scenario, the episode seed and the settings, so they are the same
whatever the number of worker processes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pnp_twin.learning.envs.driver import EnvError, check_rules
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.feeder import Feeder, resampled, splice
from pnp_twin.twin.line import Line
from pnp_twin.twin.scenario import Scenario


@dataclass(frozen=True)
class LabelSettings:
    """How one episode is labelled (recorded in the checkpoint)."""

    rules: tuple[str, ...] = ("FIFO", "LIFO", "SD", "LD", "SPT")
    """The options; the base rule must be one of them; SIRO is not (its choice is random)."""
    base: str = "SPT"
    """The rule the rollouts continue with, and the behaviour of the episodes."""
    explore: float = 0.15
    """Probability that an episode decision uses a random other rule."""
    episode_time: float = 11.0
    """Feeding time of an episode, s."""
    window: tuple[float, float] = (3.0, 8.0)
    """Decisions made in this window of the episode (s) are labelled."""
    futures: int = 12
    """Sampled futures per decision."""
    horizon: float = 3.0
    """Parts fed up to this long after the decision count, s."""
    channels: int = 2
    """Observation channels: parts, claimed parts."""

    def check(self) -> None:
        """Raise :class:`EnvError` (one line) for rules that cannot be labelled."""
        rules = check_rules(list(self.rules))
        if "SIRO" in rules:
            raise EnvError("rules: SIRO chooses at random, so it cannot be labelled; leave it out")
        if self.base not in rules:
            raise EnvError(f"base: '{self.base}' must be one of the rules ({', '.join(rules)})")


@dataclass
class Labels:
    """Label rows: ``obs`` (n, C, H, W) uint8, ``robot`` (n,), ``advantage`` (n, K)."""

    obs: np.ndarray
    robot: np.ndarray
    advantage: np.ndarray

    @classmethod
    def empty(cls, shape: tuple[int, int, int], k: int) -> Labels:
        return cls(np.zeros((0, *shape), np.uint8), np.zeros(0, np.int64), np.zeros((0, k)))

    @classmethod
    def concat(cls, parts: list[Labels]) -> Labels:
        return cls(
            np.concatenate([p.obs for p in parts]),
            np.concatenate([p.robot for p in parts]),
            np.concatenate([p.advantage for p in parts]),
        )

    def __len__(self) -> int:
        return len(self.robot)


class _Replay:
    """Replays recorded part choices, then one forced choice, then the base rule."""

    name = "rollout-replay"

    def __init__(self, prefix: list[int], forced: int | None, base: str) -> None:
        self.prefix, self.forced, self.base = prefix, forced, RULES[base]
        self.j = 0
        self.rng = np.random.default_rng(0)

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.rng, self.j = rng, 0

    def choose(self, d: Decision) -> int:
        j, self.j = self.j, self.j + 1
        if j < len(self.prefix):
            return self.prefix[j]
        if j == len(self.prefix) and self.forced is not None:
            return self.forced
        return self.base(d, self.rng)


@dataclass
class _Record:
    time: float
    robot: int
    picks: list[int]  # the part index each rule of the settings would take
    obs: np.ndarray


class _Behaviour:
    """The base rule, or with probability ``explore`` another rule; records each decision."""

    name = "rollout-behaviour"

    def __init__(self, settings: LabelSettings, rng: np.random.Generator) -> None:
        self.s, self.explore_rng = settings, rng
        self.others = [r for r in settings.rules if r != settings.base]
        self.records: list[_Record] = []
        self.chosen: list[int] = []
        self.camera: BeltCamera | None = None
        self.rng = np.random.default_rng(0)

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        self.rng = rng

    def choose(self, d: Decision) -> int:
        assert self.camera is not None
        picks = [RULES[r](d, self.rng) for r in self.s.rules]
        rule = self.s.base
        if self.others and self.explore_rng.random() < self.s.explore:
            rule = self.others[int(self.explore_rng.integers(len(self.others)))]
        k = picks[self.s.rules.index(rule)]
        self.records.append(_Record(d.time, d.robot, picks, self.camera.belt(d.time)))
        self.chosen.append(k)
        return k


def _gripped(line: Line, lo: float, hi: float) -> int:
    """Parts fed in [lo, hi) that were gripped (the line has run past their exit)."""
    fed, picked = line.belt.fed, line.recorder.picked_at
    return sum(1 for f, p in zip(fed, picked, strict=True) if lo <= f < hi and not math.isnan(p))


def future_seed(episode: int, decision: int, sample: int) -> int:
    """Seed of a sampled future: distinct per (episode, decision, sample)."""
    return int(np.random.SeedSequence([episode, decision, sample]).generate_state(1)[0])


def label_episode(
    scenario: Scenario, seed: int, settings: LabelSettings, engine: str = "fast"
) -> Labels:
    """Run one episode (``scenario`` under t_continue, feeding ``episode_time`` s) and label
    its decisions in the window; see the module docstring.

    ``engine`` "fast" (or "auto") forks the compiled line at each labelled decision and runs
    all its continuations in one compiled call (:func:`twin.fast.rollouts.continue_each`);
    "simpy" replays each continuation from t = 0 on the SimPy twin. The labels are the same.
    """
    if engine == "simpy":
        return _label_replaying(scenario, seed, settings)
    return _label_forking(scenario, seed, settings)


def _label_forking(scenario: Scenario, seed: int, s: LabelSettings) -> Labels:
    from pnp_twin.twin.fast import layout as L
    from pnp_twin.twin.fast.engine import FastLine
    from pnp_twin.twin.fast.rollouts import continue_each

    behaviour = _Behaviour(s, np.random.default_rng([seed, 1]))
    line = FastLine(scenario, behaviour, seed=seed, duration=s.episode_time)
    _, siro_room, exp_room = line._rooms()
    line.start(0, siro_room, exp_room)  # no span buffer: labels read no spans
    camera = BeltCamera(scenario, s.channels)
    camera.attach(line.belt)
    behaviour.camera = camera
    transit = line.last_end / scenario.belt.speed
    own = (line.fed, line.y, line.kind)
    rows = []
    while (status := line.advance(s.window[1])) == L.ST_CHOOSE:
        t = line.now
        fork = line.fork() if s.window[0] <= t else None
        line.answer()
        j = len(behaviour.records) - 1
        rec = behaviour.records[j]
        if fork is None or len(set(rec.picks)) < 2:
            continue
        lo, hi = t - transit, t + s.horizon
        picks = list(dict.fromkeys(rec.picks))
        other = (Feeder.seeded(scenario, future_seed(seed, j, m)) for m in range(s.futures))
        futures = [splice(own, f.stream(s.episode_time), t)[:2] for f in other]
        n_kept = int(np.searchsorted(line.fed, t, "right"))
        stop = min(line.end_at, hi + transit)
        counts = continue_each(fork, futures, n_kept, picks, s.base, stop, (lo, hi))
        if counts is None:  # a pre-drawn stream ran out: replay these continuations
            total = _replayed_totals(scenario, seed, s, behaviour.chosen[:j], rec, j, transit)
        else:
            total = {p: float(c) for p, c in zip(picks, counts, strict=True)}
        rows.append(_row(rec, total, s))
    if status != L.ST_OK:  # not expected: the line grows its streams as it goes
        raise RuntimeError(f"rollout labels: the episode stopped with status {status}")
    return _labels(rows, camera.shape, len(s.rules))


def _label_replaying(scenario: Scenario, seed: int, s: LabelSettings) -> Labels:
    behaviour = _Behaviour(s, np.random.default_rng([seed, 1]))
    line = Line(scenario, behaviour, seed=seed, duration=s.episode_time)
    camera = BeltCamera(scenario, s.channels)
    camera.attach(line.belt)
    behaviour.camera = camera
    line.run()
    transit = line.last_end / scenario.belt.speed
    rows = []
    for j, rec in enumerate(behaviour.records):
        if not s.window[0] <= rec.time < s.window[1] or len(set(rec.picks)) < 2:
            continue
        total = _replayed_totals(scenario, seed, s, behaviour.chosen[:j], rec, j, transit)
        rows.append(_row(rec, total, s))
    return _labels(rows, camera.shape, len(s.rules))


def _replayed_totals(
    scenario: Scenario,
    seed: int,
    s: LabelSettings,
    prefix: list[int],
    rec: _Record,
    j: int,
    transit: float,
) -> dict[int, float]:
    """Grips in the label's window per distinct pick, summed over the sampled futures, each
    continuation replayed from t = 0 with the recorded choices."""
    lo, hi = rec.time - transit, rec.time + s.horizon
    total = dict.fromkeys(rec.picks, 0.0)
    for m in range(s.futures):
        future = resampled(scenario, seed, future_seed(seed, j, m), rec.time, s.episode_time)
        for part in total:
            run = Line(
                scenario,
                _Replay(prefix, part, s.base),
                seed=seed,
                duration=s.episode_time,
                parts=future,
            )
            run.env.run(until=min(run.end_at, hi + transit))
            total[part] += _gripped(run, lo, hi)
    return total


def _row(rec: _Record, total: dict[int, float], s: LabelSettings) -> tuple[Any, int, Any]:
    q = np.array([total[p] / s.futures for p in rec.picks])
    return rec.obs, rec.robot, q - q[s.rules.index(s.base)]


def _labels(rows: list[tuple[Any, int, Any]], shape: tuple[int, int, int], k: int) -> Labels:
    if not rows:
        return Labels.empty(shape, k)
    obs, robots, adv = zip(*rows, strict=True)
    return Labels(np.stack(obs), np.asarray(robots, np.int64), np.asarray(adv))
