"""``tune``: the settings of a controller's balancing mode that serve the line best.

The question a line integrator asks before commissioning: which shares (or lanes) to type
into the conveyor-tracking controller. For a balancing mode (:mod:`policies.balancing`) and
a rule within it, an optimiser (optuna's TPE, seeded) proposes settings, each scored by its
mean gripping rate over the same tuning seeds (common random numbers):

- ``share``: a percentage per robot, the last robot 100 % (what reaches it is its own);
- ``lane``: N - 1 cuts across the belt, robot i owning the i-th band from the lower edge.

Without a target the best mean G wins. With ``target`` the settings that reach it (on the
tuning seeds) win by the fewest parts passed on from robot to robot (a balanced line), and
the best G where none reaches it. The chosen settings are then run on evaluation seeds that
played no part in choosing them (so the interval holds after the selection), beside the best
rule (chosen on the tuning seeds) and the lookahead controller on the same seeds: the answer
is the line to type into the controller and how sure it is.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pnp_twin.policies import make_policy
from pnp_twin.policies.balancing import BalancingSettings
from pnp_twin.policies.rules import RULES
from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.budget import estimate_run
from pnp_twin.twin.errors import excerpt
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import percent_interval
from pnp_twin.twin.trace import check_replications, for_replication

log = logging.getLogger(__name__)

STRATEGIES = ("share", "lane")
TUNING_SEED_BASE = 800_000  # the tuning seeds: apart from the evaluation seeds 0..N-1
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class TuneSettings:
    """One tuning question (the command line builds it, :func:`run_tune` reads it)."""

    strategy: str = "share"
    rule: str = "FIFO"
    """The order within what each robot owns."""
    target: float | None = None
    """G to reach (%), then the fewest parts passed on; None: the highest G."""
    trials: int = 40
    """Settings the optimiser tries."""
    tuning_seeds: int = 4
    seeds: int = 10
    """Evaluation seeds first_seed..first_seed+seeds-1."""
    first_seed: int = 0
    release: bool = False
    """unreached=release: a part its owner misses goes on to the robots downstream."""
    lookahead: str = "lookahead"
    engine: str = "fast"
    workers: int = 1
    confidence: float = 0.95
    optimiser_seed: int = 0

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.first_seed, self.first_seed + self.seeds))

    @property
    def tuning_list(self) -> list[int]:
        return [TUNING_SEED_BASE + i for i in range(self.tuning_seeds)]


@dataclass
class Scored:
    """A policy's G per seed and parts passed on per seed, with its interval."""

    policy: str
    g: list[float]
    passed: list[float]
    mean: float = math.nan
    low: float = math.nan
    high: float = math.nan

    def __post_init__(self) -> None:
        if len(self.g) >= 2:
            self.mean, self.low, self.high = percent_interval(self.g, 0.95)
        elif self.g:
            self.mean = self.low = self.high = self.g[0]

    def row(self) -> dict[str, Any]:
        return {
            "policy": self.policy,
            "gripping_rate": self.mean,
            "ci_low": self.low,
            "ci_high": self.high,
            "passed_on": float(np.mean(self.passed)) if self.passed else math.nan,
        }


@dataclass
class Tuned:
    """The answer of :func:`run_tune`."""

    scenario: Scenario
    settings: TuneSettings
    best: BalancingSettings
    tuned: Scored  # the chosen settings on the evaluation seeds
    rule: Scored  # the best rule (chosen on the tuning seeds) on the same seeds
    lookahead: Scored
    trials: list[dict[str, Any]] = field(default_factory=list)

    def answer(self) -> str:
        s = self.settings
        t = self.tuned
        goal = (
            ""
            if s.target is None
            else f" (target {s.target:g} %: "
            + ("met" if t.low >= s.target else "not met")
            + f" with {100 * s.confidence:g} % confidence)"
        )
        return (
            f"Type into the controller ({s.strategy} balancing, rule {s.rule}"
            f"{', unreached parts released downstream' if s.release else ''}): "
            f"{self.best.controller_line()}. On {len(t.g)} fresh seeds G = {t.mean:.2f} % "
            f"[{t.low:.2f}, {t.high:.2f}]{goal}; the best rule {self.rule.policy} "
            f"{self.rule.mean:.2f} % [{self.rule.low:.2f}, {self.rule.high:.2f}], the "
            f"lookahead {self.lookahead.mean:.2f} % [{self.lookahead.low:.2f}, "
            f"{self.lookahead.high:.2f}] on the same seeds."
        )

    def to_json(self) -> dict[str, Any]:
        s = self.settings
        return {
            "scenario": self.scenario.name,
            "strategy": s.strategy,
            "rule": s.rule,
            "target": s.target,
            "release": s.release,
            "policy": self.best.name,
            "controller": self.best.controller_line(),
            "shares": list(self.best.shares) or None,
            "lanes": [list(x) for x in self.best.lanes] or None,
            "tuning_seeds": s.tuning_list,
            "seeds": s.seed_list,
            "confidence": s.confidence,
            "tuned": self.tuned.row(),
            "best_rule": self.rule.row(),
            "lookahead": self.lookahead.row(),
            "trials": len(self.trials),
            "duration": self.scenario.duration,
            "warmup": self.scenario.warmup,
            "termination": self.scenario.termination,
            "answer": self.answer(),
        }


def check_tune(scenario: Scenario, settings: TuneSettings) -> None:
    """Everything that can be refused before anything runs (one-line StudyError)."""
    if settings.strategy not in STRATEGIES:
        raise StudyError(
            f"--strategy: '{settings.strategy}' is not allowed; allowed {', '.join(STRATEGIES)}"
        )
    if settings.rule not in (*RULES, "VAL"):
        raise StudyError(
            f"--rule: {excerpt(settings.rule, 40)} is not a rule; allowed {', '.join(RULES)}"
        )
    if scenario.robots.count < 2:
        raise StudyError(f"tune: {scenario.name} has one robot; there is nothing to balance")
    check_replications(scenario, max(settings.seeds, settings.tuning_seeds), "--seeds")
    if settings.target is not None and not 0 < settings.target <= 100:
        raise StudyError(f"--target: {settings.target:g} is outside 0..100 (% of parts)")
    make_policy(settings.lookahead, scenario.robots.count)


def proposal(trial: Any, scenario: Scenario, settings: TuneSettings) -> BalancingSettings:
    """The balancing settings optuna's ``trial`` proposes."""
    n = scenario.robots.count
    extra = {"rule": settings.rule, "release": settings.release}
    if settings.strategy == "share":
        shares = [float(trial.suggest_int(f"share_{i + 1}", 0, 100)) for i in range(n - 1)]
        return BalancingSettings("share", shares=(*shares, 100.0), **extra)  # type: ignore[arg-type]
    width = scenario.belt.width
    cuts = sorted(round(trial.suggest_float(f"cut_{i + 1}", 0.0, width), 4) for i in range(n - 1))
    edges = [0.0, *cuts, width]
    lanes = tuple((edges[i], edges[i + 1]) for i in range(n))
    if any(hi <= lo for lo, hi in lanes):  # two cuts at one place: a robot without a lane
        lanes = tuple((width * i / n, width * (i + 1) / n) for i in range(n))
    return BalancingSettings("lane", lanes=lanes, **extra)  # type: ignore[arg-type]


def _one(job: tuple[Scenario, str, int, str]) -> tuple[float, float]:
    """G and parts passed on (robot to robot) of one run."""
    scenario, spec, seed, engine = job
    kpis = simulate(scenario, make_policy(spec, scenario.robots.count), seed=seed, engine=engine)
    k = kpis.kpis
    return float(k["gripping_rate"]), float(sum(r["passed_on"] for r in k["robots"]))


POOL_PARTS = 200_000  # parts below which a worker pool costs more than it saves (~2 s)


def score(scenario: Scenario, spec: str, seeds: Sequence[int], settings: TuneSettings) -> Scored:
    """``spec`` run on ``seeds`` (in ``settings.workers`` processes)."""
    from pnp_twin.parallel import pool_map_ordered

    jobs = [(for_replication(scenario, k), spec, s, settings.engine) for k, s in enumerate(seeds)]
    parts = estimate_run(scenario).parts * len(jobs)  # a pool costs seconds to start
    if settings.workers > 1 and len(jobs) > 1 and parts >= POOL_PARTS:
        out = pool_map_ordered(_one, jobs, settings.workers)
    else:
        out = [_one(job) for job in jobs]
    return Scored(spec, [g for g, _ in out], [p for _, p in out])


def objective(scored: Scored, target: float | None) -> float:
    """What the optimiser maximises: mean G; with a target, reaching it first, then the
    fewest parts passed on (a settings that misses it ranks below every one that meets it)."""
    mean = float(np.mean(scored.g))
    if target is None:
        return mean
    if mean >= target:
        return 1e6 - float(np.mean(scored.passed))
    return mean - 1e6


def run_tune(scenario: Scenario, settings: TuneSettings, progress: Progress | None = None) -> Tuned:
    """Run the study (see the module docstring)."""
    import optuna

    check_tune(scenario, settings)
    tuning = settings.tuning_list
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = optuna.samplers.TPESampler(seed=settings.optimiser_seed)
    study = optuna.create_study(direction="maximize", sampler=sampler)
    seen: dict[str, Scored] = {}
    trials: list[dict[str, Any]] = []
    for k in range(settings.trials):
        trial = study.ask()
        candidate = proposal(trial, scenario, settings)
        scored = seen.get(candidate.name) or score(scenario, candidate.name, tuning, settings)
        seen[candidate.name] = scored
        value = objective(scored, settings.target)
        study.tell(trial, value)
        trials.append({"trial": k, **scored.row(), "objective": value})
        if progress is not None:
            progress("trials", k + 1, settings.trials)
    best_name = max(seen, key=lambda n: (objective(seen[n], settings.target), n))
    best = make_policy(best_name, scenario.robots.count).settings  # type: ignore[attr-defined]
    rules = {r: score(scenario, r, tuning, settings) for r in RULES}
    names = list(RULES)
    best_rule = max(names, key=lambda r: (float(np.mean(rules[r].g)), -names.index(r)))
    seeds = settings.seed_list
    tuned = score(scenario, best_name, seeds, settings)
    if progress is not None:
        progress("evaluation", 1, 3)
    rule = score(scenario, best_rule, seeds, settings)
    look = score(scenario, settings.lookahead, seeds, settings)
    if progress is not None:
        progress("evaluation", 3, 3)
    return Tuned(scenario, settings, best, tuned, rule, look, trials)
