"""A study plan: grid points x policies x replications, expanded into run specs.

Everything a study will run is decided and validated here, before the first run: each
swept path must be a field of the Scenario model, each grid point's scenario must validate
(``twin.loader.with_overrides``), and each policy must be known for that point's robot
count. A mistake is a one-line :class:`StudyError` naming the path and the value.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from types import UnionType
from typing import Any, get_args

from pydantic import BaseModel

from pnp_twin.policies import make_policy
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.errors import UserError, excerpt
from pnp_twin.twin.loader import ScenarioError, with_overrides
from pnp_twin.twin.scenario import Scenario, SweepConfig, duplicate_policy, repeated_value
from pnp_twin.twin.trace import check_replay, trace_files

RESERVED = {
    "sweep": "the study itself cannot be swept",
    "seed": "replication seeds come from the master seed; use --replications",
    "name": "the scenario name is not a line parameter",
    "description": "the description is not a line parameter",
    "source_dir": "source_dir is set by the loader",
}


AUTO = "auto"
DEFAULT_MAX_REPLICATIONS = 30
FIRST_ROUND = 3  # replications of the first round of an "auto" study


class StudyError(UserError):
    """A mistake in a study definition or its output folder; the message is one line."""


@dataclass(frozen=True)
class Precision:
    """``replications = "auto"``: add replications in rounds until the CI half-width of
    ``kpi`` (the mean's, at the study's confidence) is at most ``half_width`` at every
    point x policy, or ``max_replications`` is reached."""

    half_width: float
    max_replications: int
    kpi: str = "gripping_rate"
    first_round: int = FIRST_ROUND


@dataclass(frozen=True)
class RunSpec:
    """One run of a study: what the backends hand to ``pnp_twin.studies.execute.execute``."""

    run_id: str
    point: int
    values: dict[str, Any]
    policy: str
    replication: int
    seed: int
    scenario: Scenario
    engine: str = "auto"  # twin.run.simulate's engine: simpy | fast | auto (same results)


@dataclass(frozen=True)
class StudyPlan:
    """A validated study: the base scenario, the grid, the policies and the replications."""

    scenario: Scenario
    grid: dict[str, tuple[Any, ...]]
    policies: tuple[str, ...]
    replications: int
    master_seed: int
    points: tuple[dict[str, Any], ...]
    scenarios: tuple[Scenario, ...] = field(repr=False)
    precision: Precision | None = None

    def with_replications(self, n: int) -> StudyPlan:
        """The same study with ``n`` replications (replication k keeps its seed)."""
        return replace(self, replications=n)

    @property
    def seeds(self) -> list[int]:
        """The seed of each replication (common to every point and policy)."""
        return replication_seeds(self.master_seed, self.replications)

    def specs(self) -> list[RunSpec]:
        """Every run, ordered by point, policy, replication."""
        seeds = self.seeds
        out = []
        for p, (values, sc) in enumerate(zip(self.points, self.scenarios, strict=True)):
            for policy in self.policies:
                for k, seed in enumerate(seeds):
                    rid = run_id(p, policy, k)
                    out.append(RunSpec(rid, p, values, policy, k, seed, sc))
        return out

    def definition(self) -> dict[str, Any]:
        """What identifies the study (for resume): a changed definition is a new study."""
        return {
            "scenario": self.scenario.model_dump(mode="json", exclude={"source_dir"}),
            "grid": {k: list(v) for k, v in self.grid.items()},
            "policies": list(self.policies),
            "replications": AUTO if self.precision else self.replications,
            "master_seed": self.master_seed,
            **({"precision": asdict(self.precision)} if self.precision else {}),
        }


def run_id(point: int, policy: str, replication: int) -> str:
    """A stable, file-name-safe id, e.g. ``p003-SPT-SPT-SPT-FIFO-r01``."""
    slug = re.sub(r"[^A-Za-z0-9]+", "-", policy).strip("-") or "policy"
    if slug.replace("-", ",") != policy.upper() and slug != policy:
        slug += "-" + hashlib.sha1(policy.encode()).hexdigest()[:6]
    return f"p{point:03d}-{slug}-r{replication:02d}"


def field_path_error(path: str) -> str | None:
    """Why ``path`` is not a sweepable Scenario field, or None if it is one."""
    keys = path.split(".")
    if keys[0] in RESERVED:
        return f"sweep.grid: '{path}' cannot be swept; {RESERVED[keys[0]]}"
    model: type[BaseModel] | None = Scenario
    for depth, key in enumerate(keys):
        if model is None:
            parent = ".".join(keys[:depth])
            return f"sweep.grid: '{path}' is not a scenario field; '{parent}' is a value"
        fields = model.model_fields
        if key not in fields:
            prefix = ".".join(keys[:depth])
            allowed = ", ".join(f"{prefix + '.' if prefix else ''}{k}" for k in fields)
            return f"sweep.grid: '{path}' is not a scenario field; allowed {allowed}"
        ann = fields[key].annotation
        options = get_args(ann) if isinstance(ann, UnionType) else (ann,)  # [outfeed]: or None
        model = next((a for a in options if isinstance(a, type) and issubclass(a, BaseModel)), None)
    if model is not None:
        return f"sweep.grid: '{path}' is a section; sweep one of its fields ('{path}.…')"
    if path == "policy":  # every point runs every policy of the study
        return (
            "sweep.grid: 'policy' cannot be swept; compare policies with sweep.policies or "
            "--policy (each is run at every point)"
        )
    return None


def _point_error(values: Mapping[str, Any], message: str) -> str:
    """Name the swept path and value the validation message is about, if one is."""
    for path, value in values.items():
        if message.startswith(path):
            return f"sweep.grid.{path} = {json.dumps(value)}: {message}"
    where = ", ".join(f"{k}={json.dumps(v)}" for k, v in values.items())
    return f"sweep point ({where}): {message}"


def expand_grid(grid: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The grid's points (the product of the value lists), last path varying fastest."""
    paths = list(grid)
    return [dict(zip(paths, combo, strict=True)) for combo in itertools.product(*grid.values())]


def build_plan(
    scenario: Scenario,
    grid: Mapping[str, Sequence[Any]] | None = None,
    policies: Sequence[str] | None = None,
    replications: int | str | None = None,
    duration: float | None = None,
    warmup: float | None = None,
    half_width: float | None = None,
    max_replications: int | None = None,
) -> StudyPlan:
    """Validate a study; arguments override the scenario's ``sweep`` section."""
    sweep = scenario.sweep
    grid = dict(grid if grid is not None else (sweep.grid if sweep else {}))
    if policies is None or len(policies) == 0:
        policies = list(sweep.policies) if sweep and sweep.policies else [scenario.policy]
    reps, precision = _replications(sweep, replications, half_width, max_replications)
    base: dict[str, Any] = {}
    d = duration if duration is not None else (sweep.duration if sweep else None)
    w = warmup if warmup is not None else (sweep.warmup if sweep else None)
    if d is not None:
        base["duration"] = d
    if w is not None:
        base["warmup"] = w
    try:
        resolved = with_overrides(scenario, base) if base else scenario
        check_replay(resolved)  # a replayed trace must cover the study's duration
    except ScenarioError as e:
        raise StudyError(f"sweep: {e}") from None
    for path, values in grid.items():
        problem = field_path_error(path)
        if problem:
            raise StudyError(problem)
        if isinstance(values, str | bytes) or not isinstance(values, Sequence) or not values:
            raise StudyError(
                f"sweep.grid.{path}: {excerpt(values)} is not a non-empty list of values"
            )
        twice = repeated_value(values)
        if twice is not None:
            raise StudyError(
                f"sweep.grid.{path}: {excerpt(twice)} is given twice; give each value once "
                "(a repeated value runs the same point twice)"
            )
    twice = duplicate_policy(policies)
    if twice:
        raise StudyError(f"--policy: {twice} (names are case-insensitive); name each policy once")
    points = expand_grid(grid)
    scenarios = []
    for point in points:
        try:
            sc = with_overrides(resolved, point)
            if point and sc.feeder.arrival == "trace":
                check_replay(sc)  # each point's duration must stay inside every trace
        except ScenarioError as e:
            raise StudyError(_point_error(point, str(e))) from None
        _check_traces(sc, reps, precision)
        for name in policies:
            try:
                make_policy(name, sc.robots.count)
            except UserError as e:
                raise StudyError(f"sweep.policies: {e}") from None
        scenarios.append(sc)
    return StudyPlan(
        scenario=resolved,
        grid={k: tuple(v) for k, v in grid.items()},
        policies=tuple(policies),
        replications=int(reps),
        master_seed=scenario.seed,
        points=tuple(points),
        scenarios=tuple(scenarios),
        precision=precision,
    )


def _check_traces(sc: Scenario, reps: int, precision: Precision | None) -> None:
    """With several traces replication k replays trace k: a study may run at most as many
    replications as there are traces (one line otherwise)."""
    try:
        files = trace_files(sc)
    except ScenarioError as e:
        raise StudyError(f"sweep: {e}") from None
    most = precision.max_replications if precision else reps
    if len(files) > 1 and most > len(files):
        which = "--max-replications" if precision else "--replications"
        raise StudyError(
            f"{which}: {most}, but feeder.trace names {len(files)} traces and replication k "
            f"replays trace k; give {which} {len(files)} or fewer, or more traces"
        )


def _replications(
    sweep: SweepConfig | None,
    replications: int | str | None,
    half_width: float | None,
    max_replications: int | None,
) -> tuple[int, Precision | None]:
    """The (first) replication count and, for "auto", the precision rule."""
    reps = replications if replications is not None else (sweep.replications if sweep else 5)
    if reps != AUTO:
        if isinstance(reps, bool) or not isinstance(reps, int) or reps < 1:
            raise StudyError(f"--replications: {reps!r} is not allowed; give 1 or more, or auto")
        if half_width is not None or max_replications is not None:
            which = "--half-width" if half_width is not None else "--max-replications"
            raise StudyError(f"{which}: only with --replications auto (now {reps})")
        return reps, None
    hw = half_width if half_width is not None else (sweep.half_width if sweep else None)
    if hw is None:
        raise StudyError(
            "--half-width: replications = auto needs the target CI half-width of the gripping "
            "rate, in percentage points (e.g. --half-width 0.5 or sweep.half_width)"
        )
    if not (isinstance(hw, int | float) and math.isfinite(hw) and 0.01 <= hw <= 100):
        raise StudyError(f"--half-width: {hw!r} is not allowed; give 0.01 <= points <= 100")
    top = (
        max_replications
        if max_replications is not None
        else (
            sweep.max_replications if sweep and sweep.max_replications else DEFAULT_MAX_REPLICATIONS
        )
    )
    if not 2 <= top <= 10_000:
        raise StudyError(f"--max-replications: {top} is not allowed; give 2 to 10000")
    precision = Precision(float(hw), int(top))
    return min(precision.first_round, top), precision
