"""How much could smarter coordination gain on one line? The ``headroom`` study.

On one scenario and ``seeds`` held-out seeds (0..N-1, common random numbers: every policy
sees the same part stream), it measures

- every rule, and the **best rule** (the reference: the best mean gripping rate on these
  seeds, so the gains below are not flattered by a weak reference);
- the **best static mix** (a rule per robot, found by coordinate ascent from the best
  uniform rule on separate tuning seeds, 600,000 + i, as ``evaluate`` finds it), or a given
  one;
- any given policies (a trained HDQN: ``hdqn:DIR``);
- the **lookahead** controller (:mod:`policies.lookahead`: one-step rollout over sampled
  futures with rule continuations);
- the clairvoyant **bound**: the same planner told the true future (``oracle=1``). It bounds
  what one-step lookahead with rule continuations can gain, not what every possible
  controller can.

Each with its gripping rate and 95 % t-interval, and the paired difference to the best
rule with its 95 % t-interval (the per-seed differences under common random numbers).
:func:`answer` says it in one sentence, in points and in parts per hour.

Given a runs store (:mod:`pnp_twin.studies.headroom_runs`), every run is stored the moment it
finishes and read back instead of simulated when asked again, so a killed study resumes with
the results of an uninterrupted one.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pnp_twin.policies.registry import make_policy
from pnp_twin.policies.rules import NAMED_RULES, RULES
from pnp_twin.studies.headroom_runs import One, from_row, run_key, scene, to_row
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice
from pnp_twin.studies.runstore import RunStore
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import percent_interval, t_interval
from pnp_twin.twin.trace import check_replications, for_replication

log = logging.getLogger(__name__)

TUNING_SEED_BASE = 600_000
BOUND_NOTE = (
    "the bound is the lookahead planner told the true future arrivals (and failure times): "
    "it bounds one-step lookahead with rule continuations, not every possible controller"
)
ROLES = ("rule", "best_mix", "policy", "lookahead", "bound")


@dataclass(frozen=True)
class HeadroomSettings:
    """What one headroom study runs."""

    seeds: int = 20
    """Evaluation seeds first_seed..first_seed+seeds-1."""
    first_seed: int = 0
    policies: tuple[str, ...] = ()
    """Other policies to place (e.g. ``hdqn:models/paper_baseline__async_rollout``)."""
    lookahead: str = "lookahead"
    """The lookahead controller's name (its settings: ``lookahead:K=32,H=1.5,base=SD``)."""
    mix: str | None = None
    """The best static mix; None: searched on tuning seeds."""
    tuning_seeds: int = 3
    engine: str = "fast"
    workers: int = 1
    backend: str = "local"
    """Where the runs execute: ``local`` (processes, for the costly policies) or ``ray``."""
    address: str | None = None
    """The Ray cluster (``--address``; default RAY_ADDRESS, else a local Ray)."""
    confidence: float = 0.95
    kpi: KpiChoice = GRIPPING
    """The figure compared (``--kpi``): G, the value rate or one kind's G; the entries'
    ``gripping_rate``, ``ci_low``, ``ci_high`` and gains are on it."""

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.first_seed, self.first_seed + self.seeds))

    @property
    def bound(self) -> str:
        """The clairvoyant variant of :attr:`lookahead` (same horizon and base rule)."""
        from pnp_twin.policies.lookahead import LookaheadSettings, parse

        _, _, arg = self.lookahead.partition(":")
        s = parse(arg)
        return LookaheadSettings(s.futures, s.horizon, s.base, oracle=True).name


@dataclass
class Entry:
    """One policy's results: per-seed gripping rates, its interval, its paired gain."""

    role: str
    policy: str
    values: list[float]
    gripping_rate: float = math.nan
    ci_low: float = math.nan
    ci_high: float = math.nan
    gain: float = math.nan
    gain_ci_low: float = math.nan
    gain_ci_high: float = math.nan
    cpu_ms_per_decision: float | None = None

    def row(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in ("policy", "gripping_rate", "ci_low", "ci_high")}
        out |= {k: getattr(self, k) for k in ("gain", "gain_ci_low", "gain_ci_high")}
        if self.cpu_ms_per_decision is not None:
            out["cpu_ms_per_decision"] = self.cpu_ms_per_decision
        return out


@dataclass
class Headroom:
    """The study's result (:func:`run_headroom`)."""

    scenario: Scenario
    settings: HeadroomSettings
    rules: list[Entry]
    best_rule: Entry
    best_mix: Entry
    policies: list[Entry]
    lookahead: Entry
    bound: Entry
    tuning_seeds: list[int] = field(default_factory=list)
    part_flow: float | None = None  # parts/s presented, measured (the best rule's runs)
    # what the figure is a percentage of, per second (the best rule's runs), and its unit:
    # the part flow for G; the value presented, or the kind's parts, for another --kpi
    figure_flow: tuple[float, str] | None = None

    @property
    def entries(self) -> list[Entry]:
        return [*self.rules, self.best_mix, *self.policies, self.lookahead, self.bound]

    def to_json(self) -> dict[str, Any]:
        """``best_rule``, ``best_mix``, ``policies``, ``lookahead``, ``bound`` (each with
        policy, gripping_rate, ci_low, ci_high and the paired gain over the best rule with
        its interval), every rule, the settings and the answer in one sentence."""
        s, sc = self.settings, self.scenario
        return {
            "scenario": sc.name,
            "seeds": s.seed_list,
            "duration": sc.duration,
            "warmup": sc.warmup,
            "termination": sc.termination,
            "engine": s.engine,
            "confidence": s.confidence,
            **({} if s.kpi.default else {"kpi": s.kpi.to_json()}),
            "answer": answer(self),
            "note": BOUND_NOTE,
            "part_flow": self.part_flow,
            "best_rule": self.best_rule.row(),
            "best_mix": {**self.best_mix.row(), "tuning_seeds": self.tuning_seeds},
            "policies": [e.row() for e in self.policies],
            "lookahead": self.lookahead.row(),
            "bound": self.bound.row(),
            "rules": [e.row() for e in self.rules],
        }

    def runs(self) -> list[dict[str, Any]]:
        """One row per policy and seed: role, policy, seed, gripping_rate (the ``kpi``
        figure, which a ``kpi`` column names when it is not G)."""
        kpi = self.settings.kpi
        named = {} if kpi.default else {"kpi": kpi.name}
        return [
            {"role": e.role, "policy": e.policy, "seed": seed, "gripping_rate": g, **named}
            for e in self.entries
            for seed, g in zip(self.settings.seed_list, e.values, strict=True)
        ]


def check_policies(scenario: Scenario, settings: HeadroomSettings) -> None:
    """Every policy name is one the registry makes (a bad one: one-line PolicyError)."""
    n = scenario.robots.count
    check_replications(scenario, settings.seeds, "--seeds")  # seed k replays trace k
    if settings.mix is not None:
        _check_static_mix(settings.mix, n)
    for spec in (*settings.policies, settings.lookahead, *([settings.mix] if settings.mix else [])):
        make_policy(spec, n)
    if not settings.lookahead.strip().lower().startswith("lookahead"):
        from pnp_twin.policies.registry import PolicyError

        raise PolicyError(
            f"--lookahead: '{settings.lookahead[:60]}' is not a lookahead controller; give "
            "lookahead or lookahead:K=32,H=1.5,base=SD"
        )


def _check_static_mix(mix: str, n: int) -> None:
    """``--mix`` is reported as the best *static* mix: a rule, or one rule per robot."""
    names = [x.strip().upper() for x in mix.split(",")]
    if not all(x in NAMED_RULES for x in names):  # a wrong length: make_policy's own line
        from pnp_twin.policies.registry import PolicyError

        raise PolicyError(
            f"--mix: '{mix[:60]}' is not a static rule mix; give one rule or {n} rules, one per "
            f"robot (e.g. {','.join(['SD'] * n)}), from {', '.join(NAMED_RULES)}"
        )


Job = tuple[Scenario, str, int, str, KpiChoice]


def _one(job: Job) -> One:
    """The ``kpi`` figure of one run (G by default), the policy's CPU ms per decision when
    it reports it, the part flow measured over the window (parts presented per second) and
    the figure's own flow (:meth:`KpiChoice.flow`)."""
    scenario, spec, seed, engine, kpi = job
    policy = make_policy(spec, scenario.robots.count)
    result = simulate(scenario, policy, seed=seed, engine=engine)
    stats = getattr(policy, "stats", None)
    cpu = float(stats()["cpu_ms_per_decision"]) if callable(stats) else None
    k = result.kpis
    return kpi.of(k), cpu, float(k["part_flow"]), kpi.flow(k)


def _one_indexed(job: tuple[int, Job]) -> tuple[int, One]:
    return job[0], _one(job[1])


Progress = Callable[[str, int, int], None]


def _rates(
    scenario: Scenario,
    spec: str,
    seeds: Sequence[int],
    settings: HeadroomSettings,
    progress: Progress | None = None,
    figure: list[tuple[float, str]] | None = None,
    store: RunStore | None = None,
) -> tuple[list[float], float | None, float]:
    """The ``settings.kpi`` figure per seed (in ``settings.workers`` processes), mean CPU per
    decision and mean measured part flow (and, into ``figure``, the figure's mean flow). Runs
    in ``store`` are read back; the others are simulated and stored as each finishes."""
    from pnp_twin.parallel import pool_map, ray_map

    lines = [for_replication(scenario, k) for k in range(len(seeds))]  # seed k: trace k
    jobs = [
        (line, spec, s, settings.engine, settings.kpi) for line, s in zip(lines, seeds, strict=True)
    ]
    found: list[One | None] = [None] * len(jobs)
    keys: list[str] = []
    if store is not None:
        scenes = {id(line): scene(line) for line in lines}  # one dump unless traces differ
        keys = [
            run_key(scenes[id(line)], spec, s, settings.kpi)
            for line, s in zip(lines, seeds, strict=True)
        ]
        found = [from_row(store.get(key)) for key in keys]
    done = [0]

    def keep(pair: tuple[int, One]) -> None:
        i, one = pair
        found[i] = one
        if store is not None:
            point = {"kpi": settings.kpi.name}
            store.add(keys[i], to_row(one), label=spec, point=point, policy=spec, seed=seeds[i])
        done[0] += 1
        if progress is not None:
            progress(spec, done[0], len(jobs))

    todo = [i for i, one in enumerate(found) if one is None]
    done[0] = len(jobs) - len(todo)
    costly = ":" in spec or spec.strip().lower() == "lookahead"  # rules take milliseconds
    if settings.backend == "ray" and todo:  # every run a Ray task (same seeds, same numbers)
        ray_map(
            _one_indexed, [(i, jobs[i]) for i in todo], keep, settings.workers, settings.address
        )
    elif costly and settings.workers > 1 and len(todo) > 1:
        pool_map(_one_indexed, [(i, jobs[i]) for i in todo], keep, settings.workers)
    else:
        for i in todo:
            keep((i, _one(jobs[i])))
    if not todo and progress is not None:
        progress(spec, done[0], len(jobs))
    out = [one for one in found if one is not None]
    cpus = [c for _, c, _, _ in out if c is not None]
    flow = float(np.mean([f for _, _, f, _ in out]))
    if figure is not None:
        figure.append((float(np.mean([w[0] for *_, w in out])), out[0][3][1]))
    return [g for g, _, _, _ in out], (float(np.mean(cpus)) if cpus else None), flow


def line_rules(scenario: Scenario) -> list[str]:
    """The rules compared: the six, and VAL on a line whose kinds of part differ in value."""
    values = {k.value for k in scenario.feeder.kinds}
    return [*RULES, "VAL"] if len(values) > 1 else list(RULES)


def search_mix(
    scenario: Scenario,
    settings: HeadroomSettings,
    progress: Progress | None = None,
    store: RunStore | None = None,
) -> str:
    """The best per-robot mix by coordinate ascent from the best uniform rule, on the
    tuning seeds (the evaluation seeds are not used to choose it)."""
    n = scenario.robots.count
    seeds = [TUNING_SEED_BASE + i for i in range(settings.tuning_seeds)]
    cache: dict[tuple[str, ...], float] = {}

    def score(mix: tuple[str, ...]) -> float:
        if mix not in cache:
            spec = mix[0] if len(set(mix)) == 1 else ",".join(mix)
            cache[mix] = float(np.mean(_rates(scenario, spec, seeds, settings, store=store)[0]))
            if progress is not None:
                progress("mix search", len(cache), 0)
        return cache[mix]

    rules = line_rules(scenario)
    best = max(((r,) * n for r in rules), key=score)
    for _ in range(2):
        improved = False
        for i in range(n):
            for r in rules:
                mix = best[:i] + (r,) + best[i + 1 :]
                if score(mix) > score(best):
                    best, improved = mix, True
        if not improved:
            break
    return best[0] if len(set(best)) == 1 else ",".join(best)


def _entry(role: str, spec: str, values: list[float], ref: list[float], confidence: float) -> Entry:
    e = Entry(role, spec, values)
    e.gripping_rate, e.ci_low, e.ci_high = percent_interval(values, confidence)
    diff = list(np.asarray(values) - np.asarray(ref))
    e.gain, e.gain_ci_low, e.gain_ci_high = t_interval(diff, confidence)
    if all(d == 0.0 for d in diff):  # the reference itself: no spread, no interval
        e.gain_ci_low = e.gain_ci_high = 0.0
    return e


def run_headroom(
    scenario: Scenario,
    settings: HeadroomSettings,
    progress: Progress | None = None,
    store: RunStore | None = None,
) -> Headroom:
    """Run the study (see the module docstring), through ``store`` when given."""
    check_policies(scenario, settings)
    seeds = settings.seed_list
    c = settings.confidence
    raw: dict[str, list[float]] = {}
    flows: dict[str, float] = {}
    figure: dict[str, tuple[float, str]] = {}
    tried = line_rules(scenario)
    for rule in tried:
        got: list[tuple[float, str]] = []
        raw[rule], _, flows[rule] = _rates(scenario, rule, seeds, settings, progress, got, store)
        figure[rule] = got[0]
    best = max(tried, key=lambda r: (float(np.mean(raw[r])), -tried.index(r)))
    ref = raw[best]
    rules = [_entry("rule", r, raw[r], ref, c) for r in tried]
    best_rule = next(e for e in rules if e.policy == best)
    mix = settings.mix or search_mix(scenario, settings, progress, store)
    mix_values = raw.get(mix) or _rates(scenario, mix, seeds, settings, progress, store=store)[0]
    best_mix = _entry("best_mix", mix, mix_values, ref, c)
    policies = []
    for spec in settings.policies:
        values, cpu, _ = _rates(scenario, spec, seeds, settings, progress, store=store)
        policies.append(_entry("policy", spec, values, ref, c))
        policies[-1].cpu_ms_per_decision = cpu
    found = {}
    for role, spec in (("lookahead", settings.lookahead), ("bound", settings.bound)):
        values, cpu, _ = _rates(scenario, spec, seeds, settings, progress, store=store)
        name = str(getattr(make_policy(spec), "name", spec))  # lookahead: K=16,H=1,base=auto
        found[role] = _entry(role, name, values, ref, c)
        found[role].cpu_ms_per_decision = cpu
    tuning = [] if settings.mix else [TUNING_SEED_BASE + i for i in range(settings.tuning_seeds)]
    return Headroom(
        scenario, settings, rules, best_rule, best_mix, policies, found["lookahead"],
        found["bound"], tuning, flows[best], None if settings.kpi.default else figure[best],
    )  # fmt: skip


def _points(e: Entry) -> str:
    return f"{e.gain:+.2f} points [{e.gain_ci_low:+.2f}, {e.gain_ci_high:+.2f}]"


def answer(h: Headroom) -> str:
    """The study's answer in one sentence (points over the best rule, with the paired 95 %
    intervals, and what the lookahead's gain is worth in parts per hour)."""
    sc, b, la, bound = h.scenario, h.best_rule, h.lookahead, h.bound
    flow, unit = h.figure_flow or (h.part_flow, "parts")
    worth = ""
    if flow is not None and math.isfinite(flow) and math.isfinite(la.gain):
        amount = la.gain / 100.0 * flow * 3600.0
        big = unit != "in value" or abs(amount) >= 100  # a value may be a few euros
        worth = f", worth {amount:+,.0f}" if big else f", worth {amount:+.3g}"
        worth += f" {unit} an hour gripped"
    kpi = h.settings.kpi
    grips = (
        f"grips {b.gripping_rate:.2f} %"
        if kpi.default
        else f"reaches a {kpi.noun} of {b.gripping_rate:.2f} %"
    )
    sure = "above zero" if la.gain_ci_low > 0 else "not surely above zero"
    extra = "".join(f"; {e.policy} gets {_points(e)}" for e in h.policies)
    return (
        f"On {sc.name} the best rule, {b.policy}, {grips}; {_bound_clause(bound, la)}; "
        f"the lookahead controller gets {_points(la)} ({sure}){worth}; the best static mix "
        f"{h.best_mix.policy} gets {_points(h.best_mix)}{extra}."
    )


def _bound_clause(bound: Entry, la: Entry) -> str:
    """The clairvoyant bound's clause: "could gain up to" only where it is not below what
    the lookahead controller got (on few seeds, or with a different plan, it can be)."""
    if bound.gain >= la.gain:
        return (
            f"a smarter controller could gain up to {_points(bound)} here (the clairvoyant "
            "one-step bound)"
        )
    return (
        f"the clairvoyant one-step bound gets {_points(bound)}, below the lookahead "
        "controller here (a one-step planner told the future is no bound on a planner that "
        "looks further), so it bounds nothing on this line"
    )
