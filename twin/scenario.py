"""Scenario: the typed, validated, immutable description of one line and one run.

A scenario is data. It is read from TOML or YAML (by suffix), validated with pydantic into
frozen models, and never changed afterwards: overrides (``--set robots.arm_speed=4``) are
applied to the raw mapping *before* validation, so every value passes the same checks.

Units are SI throughout (metres, seconds, m/s, parts/s); see ``shared/MODEL.md``.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class Frozen(BaseModel):
    """Base of every scenario model: immutable, unknown keys rejected."""

    model_config = ConfigDict(frozen=True, extra="forbid")


class BeltConfig(Frozen):
    """The conveyor: a part's position is x(t) = speed * (t - fed_at)."""

    length: PositiveFloat = Field(2.4, description="Belt length L in m, from the feeder (x=0).")
    width: PositiveFloat = Field(0.4, description="Belt width W in m (y from 0 to W).")
    speed: PositiveFloat = Field(0.8, description="Belt speed v_b in m/s.")
    grid: tuple[Annotated[int, Field(ge=1, le=4096)], Annotated[int, Field(ge=1, le=1024)]] = Field(
        (64, 8), description="Observation grid: cells along the belt, cells across."
    )


class FeederConfig(Frozen):
    """Where and when parts are put on the belt at x = 0."""

    arrival: Literal["poisson", "normal", "fixed", "trace"] = Field(
        "poisson", description="Arrival process: poisson, normal gaps, fixed spacing, or trace."
    )
    rate: PositiveFloat = Field(10.0, description="Part flow f_p in parts/s (not used by trace).")
    cv: NonNegFloat = Field(
        0.3, description="Coefficient of variation of the gaps (normal arrivals only)."
    )
    trace: str | None = Field(
        None,
        description="CSV of recorded arrivals (columns time, y[, kind]); relative paths are "
        "resolved against the scenario file's folder. Required when arrival = 'trace'.",
    )
    lateral: Literal["normal", "uniform"] = Field(
        "normal", description="Lateral placement: truncated normal or uniform across the belt."
    )
    lateral_mean: NonNegFloat | None = Field(
        None, description="Mean of the truncated normal in m; default the belt centre."
    )
    lateral_sd: PositiveFloat = Field(0.08, description="SD of the truncated normal in m.")

    @model_validator(mode="after")
    def _trace_needs_file(self) -> FeederConfig:
        if self.arrival == "trace" and not self.trace:
            raise ValueError("feeder.trace: a trace file is required when arrival = 'trace'")
        return self


class RobotOverride(Frozen):
    """Per-robot overrides of the shared robot parameters; unset fields keep the default."""

    robot: Annotated[int, Field(ge=1, description="Robot number, 1 = most upstream.")]
    arm_speed: PositiveFloat | None = None
    pick_time: NonNegFloat | None = None
    place_time: NonNegFloat | None = None
    acceleration: NonNegFloat | None = None
    bin_offset: tuple[float, float] | None = None
    mtbf: NonNegFloat | None = None
    mttr: NonNegFloat | None = None


class RobotsConfig(Frozen):
    """The robots, identical by default, upstream to downstream."""

    count: Annotated[int, Field(ge=1, le=64)] = Field(4, description="Number of robots N.")
    workspaces: tuple[tuple[float, float], ...] | None = Field(
        None,
        description="Explicit workspaces [[a1, b1], ...] in m along the belt; when unset they "
        "are laid out from first_workspace_start, workspace_length and workspace_gap.",
    )
    first_workspace_start: NonNegFloat = Field(0.3, description="a_1 in m.")
    workspace_length: PositiveFloat = Field(0.5, description="b_i - a_i in m.")
    workspace_gap: NonNegFloat = Field(0.0, description="Gap between workspaces in m.")
    arm_speed: PositiveFloat = Field(3.0, description="Tool speed v_r in m/s (straight moves).")
    pick_time: NonNegFloat = Field(0.1, description="Grip time in s.")
    place_time: NonNegFloat = Field(0.1, description="Release time in s.")
    acceleration: NonNegFloat = Field(
        0.0, description="Acceleration limit in m/s^2 (trapezoidal moves); 0 = instantaneous."
    )
    bin_offset: tuple[float, float] = Field(
        (0.0, 0.2),
        description="Bin position relative to (workspace centre x, upper belt edge W), in m.",
    )
    mtbf: NonNegFloat = Field(
        0.0, description="Mean time between failures in s; 0 = no breakdowns."
    )
    mttr: NonNegFloat = Field(0.0, description="Mean time to repair in s.")
    failure_distribution: Literal["exponential", "fixed"] = Field(
        "exponential", description="Distribution of times between failures and to repair."
    )
    overrides: tuple[RobotOverride, ...] = Field(
        (), description="Per-robot overrides, e.g. [[robots.overrides]] robot = 2 arm_speed = 4."
    )

    @model_validator(mode="after")
    def _check(self) -> RobotsConfig:
        if self.workspaces is not None and len(self.workspaces) != self.count:
            raise ValueError(
                f"robots.workspaces: {len(self.workspaces)} workspaces given for "
                f"robots.count = {self.count}; give one [a, b] per robot"
            )
        seen = set()
        for o in self.overrides:
            if o.robot > self.count:
                raise ValueError(
                    f"robots.overrides.robot: {o.robot} is not a robot; allowed 1..{self.count}"
                )
            if o.robot in seen:
                raise ValueError(f"robots.overrides.robot: robot {o.robot} overridden twice")
            seen.add(o.robot)
        return self

    def layout(self) -> list[tuple[float, float]]:
        """Workspace bounds [a_i, b_i] in m, upstream first."""
        if self.workspaces is not None:
            return [(float(a), float(b)) for a, b in self.workspaces]
        a = self.first_workspace_start
        out = []
        for _ in range(self.count):
            out.append((a, a + self.workspace_length))
            a += self.workspace_length + self.workspace_gap
        return out


class BinsConfig(Frozen):
    """Packaging boxes, one per robot."""

    capacity: Annotated[int, Field(ge=0)] = Field(
        0, description="Parts per box before a box change; 0 = unlimited."
    )
    change_time: NonNegFloat = Field(
        0.0, description="Box change time in s, during which the robot cannot place."
    )


class SweepConfig(Frozen):
    """A study: a grid over scenario fields, policies to compare, replications."""

    grid: dict[str, tuple[Any, ...]] = Field(
        default_factory=dict,
        description="Dotted scenario path -> list of values; the grid is their product.",
    )
    policies: tuple[str, ...] = Field(
        (), description="Policies (names or per-robot mixes) to compare; default the scenario's."
    )
    replications: Annotated[int, Field(ge=1, le=10_000)] = 5
    duration: PositiveFloat | None = Field(None, description="Overrides the run duration, s.")
    warmup: NonNegFloat | None = Field(None, description="Overrides the warm-up, s.")
    target: Annotated[float, Field(gt=0, le=100)] | None = Field(
        None, description="Target gripping rate in percent, for sizing studies."
    )

    @field_validator("grid")
    @classmethod
    def _grid_lists(cls, v: dict[str, tuple[Any, ...]]) -> dict[str, tuple[Any, ...]]:
        for path, values in v.items():
            if len(values) == 0:
                raise ValueError(f"sweep.grid.{path}: empty list; give at least one value")
        return v


Termination = Literal["t_continue", "t_all", "t_any"]


class Scenario(Frozen):
    """One line and one run: geometry, feeder, robots, bins, policy, timing, seed."""

    name: str = Field("scenario", description="Short name, used in run and file names.")
    description: str = Field("", description="Free text shown in reports.")
    belt: BeltConfig = BeltConfig()
    feeder: FeederConfig = FeederConfig()
    robots: RobotsConfig = RobotsConfig()
    bins: BinsConfig = BinsConfig()
    policy: str = Field("SD", description="Rule name or per-robot mix, e.g. 'SPT,SPT,SPT,FIFO'.")
    termination: Termination = Field("t_continue", description="t_continue | t_all | t_any.")
    duration: PositiveFloat = Field(600.0, description="Feeding time in s (the run then drains).")
    warmup: NonNegFloat = Field(60.0, description="Parts fed before this time are not counted.")
    seed: Annotated[int, Field(ge=0)] = Field(0, description="Master seed of the run.")
    sweep: SweepConfig | None = Field(None, description="Optional study definition.")
    source_dir: str | None = Field(
        None, description="Folder of the scenario file (set by the loader; resolves trace paths)."
    )

    @model_validator(mode="after")
    def _check_line(self) -> Scenario:
        if self.warmup >= self.duration:
            raise ValueError(
                f"warmup: {self.warmup} s must be shorter than duration ({self.duration} s)"
            )
        spaces = self.robots.layout()
        prev_b = -math.inf
        for i, (a, b) in enumerate(spaces, start=1):
            if not 0 <= a < b:
                raise ValueError(f"robots.workspaces: robot {i} has [{a}, {b}]; need 0 <= a < b")
            if a < prev_b:
                raise ValueError(
                    f"robots.workspaces: robot {i} starts at {a} m inside robot {i - 1}'s "
                    f"workspace (ends {prev_b} m); workspaces must not overlap, upstream first"
                )
            prev_b = b
        if prev_b > self.belt.length + 1e-9:
            raise ValueError(
                f"robots.workspaces: the last workspace ends at {prev_b:g} m, beyond "
                f"belt.length = {self.belt.length:g} m; lengthen the belt or shrink workspaces"
            )
        for i in range(1, self.robots.count + 1):
            v_r = self.robot_param(i, "arm_speed")
            if v_r <= self.belt.speed:
                raise ValueError(
                    f"robots.arm_speed: {v_r:g} m/s for robot {i} must exceed belt.speed "
                    f"({self.belt.speed:g} m/s) or no part can be intercepted"
                )
        if self.feeder.lateral_mean is not None and self.feeder.lateral_mean > self.belt.width:
            raise ValueError(
                f"feeder.lateral_mean: {self.feeder.lateral_mean} m is off the belt; "
                f"allowed 0..{self.belt.width} (belt.width)"
            )
        if self.robots.mtbf > 0 and self.robots.mttr <= 0:
            raise ValueError("robots.mttr: must be > 0 when robots.mtbf > 0 (breakdowns on)")
        return self

    def robot_param(self, robot: int, name: str) -> Any:
        """Robot ``robot``'s (1-based) value of ``name``, its override if set."""
        for o in self.robots.overrides:
            if o.robot == robot:
                value = getattr(o, name)
                if value is not None:
                    return value
        return getattr(self.robots, name)
