"""Calibration: fit a scenario's unknown fields so the twin reproduces measured points.

A :class:`Problem` is a scenario, measured :class:`~calibrate_targets.Targets` and the
fields to fit (:class:`~calibrate_fields.FitParam`, with bounds). The objective is the
weighted sum over points and KPIs of squared residuals (predicted minus measured, scaled as
``calibrate_targets`` says). scipy's bounded Nelder-Mead minimises it in coordinates scaled
to [0, 1] per parameter, from the scenario's own values. Predictions come from
``calibrate_eval`` (best policy, common random numbers, a journal that makes a rerun resume).

After the fit, :func:`calibrate` also measures how well each parameter is determined (the
objective's profile along each parameter around the optimum, other parameters held; and a
grid over each pair, where two parameters that trade off show as a valley), and the fitted
response across each varied field. Writing the outputs is ``calibrate_output``'s job.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.policies import RULES, make_policy
from pnp_twin.studies.calibrate_eval import Evaluator, PointPrediction
from pnp_twin.studies.calibrate_fields import FieldRef, FitParam, apply_values, current_value
from pnp_twin.studies.calibrate_targets import Targets, robot_of
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_quantile
from pnp_twin.twin.trace import check_replications

log = logging.getLogger(__name__)

Progress = Callable[[int, float], None]  # (evaluations so far, best objective so far)


@dataclass(frozen=True)
class Problem:
    """What to fit: the scenario (``--set`` applied), the targets, the parameters, how."""

    scenario: Scenario
    targets: Targets
    params: tuple[FitParam, ...]
    policies: tuple[str, ...] = tuple(RULES)
    replications: int = 5
    max_evals: int = 60
    profile: int = 7  # points per parameter profile (0: none)
    pairs: int = 4  # points per side of each pair's grid (0: none)

    @property
    def seeds(self) -> list[int]:
        """Replication seeds (common to every point, policy and parameter vector)."""
        return replication_seeds(self.scenario.seed, self.replications)

    def start(self) -> np.ndarray:
        """The scenario's own values of the parameters, clipped into their bounds."""
        out = []
        for p in self.params:
            v = float(current_value(self.scenario, p.refs[0]))
            out.append(min(max(v, p.low), p.high))
        return np.array(out)

    def values(self, x: Sequence[float]) -> dict[FieldRef, float]:
        """Field -> value for a parameter vector (fields sharing a parameter get its value)."""
        return {r: float(v) for p, v in zip(self.params, x, strict=True) for r in p.refs}

    def scenarios(
        self, x: Sequence[float], points: Sequence[dict[FieldRef, Any]]
    ) -> list[Scenario]:
        """The line at each point with the parameters ``x``."""
        return [apply_values(self.scenario, {**pt, **self.values(x)}) for pt in points]


@dataclass
class Evaluation:
    """One parameter vector: the predictions at every target point and the objective."""

    x: tuple[float, ...]
    predictions: list[PointPrediction]
    residuals: np.ndarray  # points x kpis, in KPI units (NaN where not measured)
    objective: float


@dataclass
class Calibration:
    """The fit's result and the evidence for the report."""

    problem: Problem
    best: Evaluation
    history: list[tuple[tuple[float, ...], float]]
    profiles: list[list[tuple[float, float]]]  # per parameter: (value, objective)
    pairs: list[tuple[int, int, list[tuple[float, float, float]]]]  # (j, l, (xj, xl, obj))
    curves: list[tuple[FieldRef, list[tuple[Any, PointPrediction]]]]
    wall_time: float
    simulated: int
    replayed: int
    message: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def fitted(self) -> dict[str, float]:
        """Dotted path -> fitted value, for every fitted field."""
        return {r.path: v for r, v in self.problem.values(self.best.x).items()}


def label(targets: Targets, i: int) -> str:
    """A point's name in messages: its varied values, e.g. ``robots.arm_speed=2``."""
    cells = ", ".join(f"{r.path}={v}" for r, v in targets.point(i).items())
    return f"{i + 1} ({cells})" if cells else str(i + 1)


def check_problem(problem: Problem) -> None:
    """Every point validates at the start and at every corner of the bounds; every policy
    is known: a mistake is found before the first simulation."""
    t = problem.targets
    if problem.replications < 1:
        raise StudyError(f"--replications: {problem.replications} is not allowed; give 1 or more")
    check_replications(problem.scenario, problem.replications, "--replications")
    if problem.max_evals < 1:
        raise StudyError(f"--max-evals: {problem.max_evals} is not allowed; give 1 or more")
    corners = itertools.product(*[(p.low, p.high) for p in problem.params])
    for x in [tuple(problem.start()), *corners]:
        for i in range(t.n):
            try:
                sc = apply_values(problem.scenario, {**t.point(i), **problem.values(x)})
            except StudyError as e:
                raise StudyError(f"target point {label(t, i)}: {e}") from None
            for kpi in t.kpis:
                robot = robot_of(kpi)
                if robot is not None and robot > sc.robots.count:
                    raise StudyError(
                        f"--targets {t.source}: column {kpi} names robot {robot}, but the line "
                        f"at point {label(t, i)} has {sc.robots.count} robots; allowed "
                        f"r1_..r{sc.robots.count}_"
                    )
            for name in problem.policies:
                try:
                    make_policy(name, sc.robots.count)
                except UserError as e:
                    raise StudyError(f"--policy: {e}") from None


def residuals(targets: Targets, predictions: Sequence[PointPrediction]) -> np.ndarray:
    """Predicted minus measured, points x KPIs, in each KPI's units."""
    pred = np.array([[p.mean[k] for k in targets.kpis] for p in predictions])
    return pred - targets.target


def objective(targets: Targets, res: np.ndarray) -> float:
    """Weighted sum of squared scaled residuals; unmeasured cells count nothing."""
    scaled = res / targets.scale()
    return float(np.nansum(targets.weight[:, None] * scaled**2))


class Fit:
    """The objective as a function of the parameters, with progress and a record of steps."""

    def __init__(self, problem: Problem, evaluator: Evaluator, progress: Progress | None) -> None:
        self.problem = problem
        self.evaluator = evaluator
        self.progress = progress
        self.history: list[tuple[tuple[float, ...], float]] = []
        self.best: Evaluation | None = None
        self.tracking = True  # after the optimiser: keep its best, note any lower objective
        self.lower: Evaluation | None = None
        self._points = [problem.targets.point(i) for i in range(problem.targets.n)]
        self._labels = [label(problem.targets, i) for i in range(problem.targets.n)]

    def evaluate(self, x: Sequence[float]) -> Evaluation:
        """Predict every target point at ``x`` (journalled) and score it."""
        return self.evaluate_many([x])[0]

    def evaluate_many(self, xs: Sequence[Sequence[float]]) -> list[Evaluation]:
        """Evaluate several parameter vectors in one batch (parallel over ``--workers``)."""
        vectors = [tuple(float(v) for v in x) for x in xs]
        n = len(self._points)
        scenarios = [sc for x in vectors for sc in self.problem.scenarios(x, self._points)]
        preds = self.evaluator.predict(scenarios, self._labels * len(vectors))
        out = []
        for b, x in enumerate(vectors):
            mine = preds[b * n : (b + 1) * n]
            res = residuals(self.problem.targets, mine)
            ev = Evaluation(x, mine, res, objective(self.problem.targets, res))
            out.append(ev)
            self.history.append((x, ev.objective))
            if self.tracking:
                if self.best is None or ev.objective < self.best.objective:
                    self.best = ev
            elif self.best is not None:
                if ev.objective < (self.lower or self.best).objective:
                    self.lower = ev
            log.info("evaluation %d: %s -> objective %.4g", len(self.history), x, ev.objective)
            if self.progress is not None and self.best is not None:
                self.progress(len(self.history), self.best.objective)
        return out

    def scaled(self, u: np.ndarray) -> float:
        """The objective at unit coordinates ``u`` in [0, 1]^k."""
        return self.evaluate(self.to_x(u).tolist()).objective

    def to_x(self, u: np.ndarray) -> np.ndarray:
        lo = np.array([p.low for p in self.problem.params])
        hi = np.array([p.high for p in self.problem.params])
        return lo + np.clip(u, 0.0, 1.0) * (hi - lo)

    def to_u(self, x: np.ndarray) -> np.ndarray:
        lo = np.array([p.low for p in self.problem.params])
        hi = np.array([p.high for p in self.problem.params])
        return (x - lo) / (hi - lo)


def _simplex(u0: np.ndarray, step: float = 0.15) -> np.ndarray:
    """The first simplex: the start and one step along each parameter (inward at a bound)."""
    rows = [u0]
    for j in range(len(u0)):
        v = u0.copy()
        v[j] = u0[j] + step if u0[j] + step <= 1.0 else u0[j] - step
        rows.append(v)
    return np.array(rows)


def optimise(fit: Fit) -> str:
    """Minimise the objective with scipy's bounded Nelder-Mead; returns scipy's message."""
    from scipy.optimize import minimize  # imported here: ~0.5 s, and only calibrate needs it

    k = len(fit.problem.params)
    u0 = fit.to_u(fit.problem.start())
    result = minimize(
        fit.scaled,
        u0,
        method="Nelder-Mead",
        bounds=[(0.0, 1.0)] * k,
        options={
            "maxfev": fit.problem.max_evals,
            "initial_simplex": _simplex(u0),
            "xatol": 2e-3,
            "fatol": 1e-2,
        },
    )
    return str(result.message)


def _axis(p: FitParam, centre: float, n: int) -> list[float]:
    """``n`` values around ``centre``: a quarter of the bounds' width either side, clipped."""
    half = 0.25 * (p.high - p.low)
    lo, hi = max(p.low, centre - half), min(p.high, centre + half)
    return sorted({*np.linspace(lo, hi, n).tolist(), centre})


def profiles(fit: Fit, best: Sequence[float]) -> list[list[tuple[float, float]]]:
    """Per parameter, the objective along it around the optimum, the others held."""
    n = fit.problem.profile
    axes = [_axis(p, best[j], n) if n > 0 else [] for j, p in enumerate(fit.problem.params)]
    xs = []
    for j, axis in enumerate(axes):
        for v in axis:
            x = list(best)
            x[j] = v
            xs.append(x)
    objectives = iter(ev.objective for ev in fit.evaluate_many(xs)) if xs else iter(())
    return [[(v, next(objectives)) for v in axis] for axis in axes]


def pair_profiles(
    fit: Fit, best: Sequence[float]
) -> list[tuple[int, int, list[tuple[float, float, float]]]]:
    """For each pair of parameters, the objective on an n x n grid around the optimum."""
    n = fit.problem.pairs
    params = fit.problem.params
    if n < 2:
        return []
    cells = []
    for j, m in itertools.combinations(range(len(params)), 2):
        for a, b in itertools.product(_axis(params[j], best[j], n), _axis(params[m], best[m], n)):
            x = list(best)
            x[j], x[m] = a, b
            cells.append((j, m, a, b, x))
    if not cells:
        return []
    evs = fit.evaluate_many([c[4] for c in cells])
    out: dict[tuple[int, int], list[tuple[float, float, float]]] = {}
    for (j, m, a, b, _), ev in zip(cells, evs, strict=True):
        out.setdefault((j, m), []).append((a, b, ev.objective))
    return [(j, m, grid) for (j, m), grid in out.items()]


def curve_values(targets: Targets, j: int, n: int) -> list[Any]:
    """Values of varied field ``j`` for its response curve: its measured range, ``n`` steps."""
    seen = [v[j] for v in targets.values]
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in seen):
        return list(dict.fromkeys(seen))
    lo, hi = min(seen), max(seen)
    if lo == hi:
        return [lo]
    return sorted({*np.round(np.linspace(lo, hi, n), 6).tolist(), *seen})


def curves(
    fit: Fit, best: Sequence[float]
) -> list[tuple[FieldRef, list[tuple[Any, PointPrediction]]]]:
    """The fitted response across each varied field (other varied fields as at point 1)."""
    t = fit.problem.targets
    out = []
    n = max(fit.problem.profile, 5)
    for j, ref in enumerate(t.varied):
        values = curve_values(t, j, n)
        points = [{**t.point(0), ref: v} for v in values]
        labels = [f"curve {ref.path}={v}" for v in values]
        preds = fit.evaluator.predict(fit.problem.scenarios(best, points), labels)
        out.append((ref, list(zip(values, preds, strict=True))))
    return out


def calibrate(
    problem: Problem,
    folder: Path,
    workers: int = 1,
    progress: Progress | None = None,
    engine: str = "auto",
) -> Calibration:
    """Fit ``problem``, journalling every evaluation in ``folder``; see the module docstring.

    ``engine``: the simulation engine of every run (simpy | fast | auto, same results);
    ``extra["engine"]`` and ``extra["engines_ran"]`` record what was asked and what ran."""
    check_problem(problem)
    t0 = time.perf_counter()
    evaluator = Evaluator(
        folder,
        problem.policies,
        problem.seeds,
        problem.targets.kpis,
        workers=workers,
        engine=engine,
    )
    try:
        fit = Fit(problem, evaluator, progress)
        message = optimise(fit)
        assert fit.best is not None
        history = list(fit.history)
        # the file gets 4 significant digits: score exactly those values (journalled, so cheap)
        rounded = tuple(float(f"{v:.4g}") for v in fit.best.x)
        best = fit.best if rounded == fit.best.x else fit.evaluate(rounded)
        log.info("fit: %s; best objective %.4g at %s", message, best.objective, best.x)
        fit.tracking = False
        prof = profiles(fit, best.x)
        pairs = pair_profiles(fit, best.x)
        curve = curves(fit, best.x)
        return Calibration(
            problem=problem,
            best=best,
            history=history,
            profiles=prof,
            pairs=pairs,
            curves=curve,
            wall_time=time.perf_counter() - t0,
            simulated=evaluator.simulated,
            replayed=evaluator.replayed,
            message=message,
            extra={
                "engine": engine,
                "engines_ran": sorted(evaluator.engines_ran),
                **({"lower": (fit.lower.x, fit.lower.objective)} if fit.lower is not None else {}),
            },
        )
    finally:
        # closed now, not when a traceback lets it go: a failed --fresh fit puts the old
        # evals/ back, and a late close would touch the store's files by their names
        evaluator.store.close()


CHI2_1_95 = 3.841458820694124  # the 95 % quantile of chi-square with 1 degree of freedom


def noise_margin(problem: Problem, best: Evaluation) -> dict[str, float]:
    """How far above its minimum the objective may rise before a parameter value is ruled
    out at 95 %: chi-square(1) x the variance of one (weighted, scaled) residual, the larger
    of what the residuals left at the fit say (their sum over the cells beyond the fitted
    parameters) and what the seeds say (twice the squared standard error of each predicted
    mean, as measured values carry the same run-to-run noise). An objective that is only
    required to stay within +1 excludes the truth of a line it fits almost exactly."""
    t = problem.targets
    scale = t.scale()
    cells = ~np.isnan(t.target)
    m = int(cells.sum())
    dof = m - len(problem.params)
    residual = best.objective / dof if dof > 0 else 0.0
    seeds = []
    n = problem.replications
    if n >= 2:
        tq = t_quantile(0.975, n - 1)
        for i, pred in enumerate(best.predictions):
            for j, k in enumerate(t.kpis):
                lo, hi = pred.ci_low.get(k, math.nan), pred.ci_high.get(k, math.nan)
                if not cells[i, j] or not (math.isfinite(lo) and math.isfinite(hi)):
                    continue
                se = (hi - lo) / (2.0 * tq)
                seeds.append(float(t.weight[i]) * 2.0 * (se / scale[j]) ** 2)
    seed_var = float(np.mean(seeds)) if seeds else 0.0
    variance = max(residual, seed_var)
    return {
        "margin": CHI2_1_95 * variance if variance > 0 else 1.0,
        "residual_variance": residual,
        "seed_variance": seed_var,
    }


def near_optimal(
    line: Sequence[tuple[float, float]], best: float, margin: float = 1.0
) -> tuple[float, float]:
    """The span around the profile's minimum where the objective stays within ``margin`` of
    ``best``, its ends interpolated linearly between profile points (a span that reaches
    the profile's end is cut there: the parameter is at best that well determined)."""
    pts = sorted(line)
    if not pts:
        return math.nan, math.nan
    level = best + margin
    c = min(range(len(pts)), key=lambda i: pts[i][1])

    def crossing(i: int, j: int) -> float:  # pts[i] is within the level, pts[j] is above it
        (vi, oi), (vj, oj) = pts[i], pts[j]
        return vi + (vj - vi) * (level - oi) / (oj - oi) if oj != oi else vi

    lo, hi = pts[0][0], pts[-1][0]
    for j in range(c - 1, -1, -1):
        if pts[j][1] > level:
            lo = crossing(j + 1, j)
            break
    for j in range(c + 1, len(pts)):
        if pts[j][1] > level:
            hi = crossing(j - 1, j)
            break
    return lo, hi
