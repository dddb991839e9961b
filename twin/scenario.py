"""Scenario: the typed, validated, immutable description of one line and one run.

A scenario is data. It is read from TOML or YAML (by suffix), validated with pydantic into
frozen models, and never changed afterwards: overrides (``--set robots.arm_speed=4``) are
applied to the raw mapping *before* validation, so every value passes the same checks.

Validation is strict: numbers must be numbers (``count = true`` or ``rate = "10"`` are
refused, not coerced), every float must be finite, every physical quantity lies within the
bounds its field states (in the JSON Schema as ``minimum``/``maximum`` with a ``unit``), and
settings that contradict each other are refused rather than ignored. A field left out takes
the value of the shipped ``paper_baseline`` (a test keeps the two equal).

Units are SI throughout (metres, seconds, m/s, parts/s); see ``docs/model.md``.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    Strict,
    field_validator,
    model_validator,
)

from pnp_twin.twin.geometry import bin_position, mount_position, workspaces


def _integral(value: Any) -> Any:
    """numpy integers and whole floats (``4.0``) as int; anything else as it is."""
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


# Strict numbers: an int is a valid float and 4.0 a valid int, but a bool or a string is
# neither (no `count = true`, no `rate = "10"`).
Real = Annotated[float, Strict()]
INTEGRAL = BeforeValidator(_integral)  # last in an Annotated int: runs before the checks
Text = Annotated[str, Strict()]
TracePath = Annotated[str, Strict(), Field(min_length=1, max_length=4096)]
TracePaths = Annotated[tuple[TracePath, ...], Field(min_length=1, max_length=1000)]

YEAR = 31_536_000.0  # s: the longest run or warm-up a scenario may ask for
SEED_MAX = 2**63 - 1
NO_CONTROL = r"^[^\x00-\x1f\x7f]*$"  # one-line text: no newlines or other control characters


def least(minimum: float, unit: str, why: str, *, zero_is_off: bool = False) -> AfterValidator:
    """A physical lower bound on a speed, rate, length or time, stated in the error: the
    schema's ``> 0`` lets through ``1e-300``, which no line has and which would make a run
    drain for ever. With ``zero_is_off``, 0 (the feature off) is allowed too."""

    def check(value: Any) -> Any:
        if isinstance(value, int | float) and value < minimum and not (zero_is_off and value == 0):
            off = "0 (off) or " if zero_is_off else ""
            raise ValueError(
                f"{value:g} {unit} is below the physical lower bound; give {off}at least "
                f"{minimum:g} {unit} ({why})"
            )
        return value

    return AfterValidator(check)


MIN_SPEED = least(0.01, "m/s", "1 cm/s; slower never drains the belt")
MIN_LENGTH = least(0.001, "m", "1 mm")


def num(
    default: Any,
    unit: str,
    description: str,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
) -> Any:
    """A numeric field with its unit (shown in the schema and in error messages)."""
    extra: dict[str, Any] = {"unit": unit}
    return Field(default, description=description, json_schema_extra=extra, gt=gt, ge=ge, le=le)


class Frozen(BaseModel):
    """Base of every scenario model: immutable, unknown keys rejected, finite floats only."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class BeltConfig(Frozen):
    """The conveyor: a part's position is x(t) = speed * (t - fed_at)."""

    length: Annotated[Real, MIN_LENGTH] = num(
        2.4, "m", "Belt length L in m, from the feeder (x=0).", gt=0, le=1000
    )
    width: Annotated[Real, MIN_LENGTH] = num(
        0.4, "m", "Belt width W in m (y from 0 to W).", gt=0, le=10
    )
    speed: Annotated[Real, MIN_SPEED] = num(0.8, "m/s", "Belt speed v_b in m/s.", gt=0, le=10)
    grid: tuple[
        Annotated[int, Strict(), Field(ge=1, le=4096), INTEGRAL],
        Annotated[int, Strict(), Field(ge=1, le=1024), INTEGRAL],
    ] = Field((64, 8), description="Observation grid: cells along the belt, cells across.")


KindName = Annotated[Text, Field(min_length=1, max_length=64, pattern=r"^[^\x00-\x1f\x7f,]*$")]


class KindConfig(Frozen):
    """One kind of part: its share of the flow, its value, and optionally its own grip and
    release times (every robot's, for this kind)."""

    name: KindName = Field(description="Name of the kind, as a trace's kind column writes it.")
    share: Annotated[Real, Field(gt=0, le=1)] = num(
        1.0, "1", "Share of the part flow, 0 < share <= 1; the shares sum to 1."
    )
    value: Annotated[Real, Field(ge=0, le=1e9)] = num(
        1.0, "1", "Value of one part (any unit: euros, kg of material); value_rate weighs by it."
    )
    pick_time: Annotated[Real, Field(ge=0, le=60)] | None = num(
        None, "s", "Grip time of this kind in s, on every robot; default the robot's."
    )
    place_time: Annotated[Real, Field(ge=0, le=60)] | None = num(
        None, "s", "Release time of this kind in s, on every robot; default the robot's."
    )


class FeederConfig(Frozen):
    """Where and when parts are put on the belt at x = 0."""

    arrival: Literal["poisson", "normal", "fixed", "trace"] = Field(
        "poisson", description="Arrival process: poisson, normal gaps, fixed spacing, or trace."
    )
    rate: Annotated[Real, least(0.001, "parts/s", "one part in 1000 s")] = num(
        10.0, "parts/s", "Part flow f_p in parts/s (not used by trace).", gt=0, le=1000
    )
    cv: Real = num(
        0.3, "1", "Coefficient of variation of the gaps (normal arrivals only).", ge=0, le=10
    )
    trace: TracePath | TracePaths | None = Field(
        None,
        description="CSV of recorded arrivals (columns time, y[, kind]), a list of them or a "
        "folder of them (a study's replication k replays the k-th, by name); relative paths "
        "are resolved against the scenario file's folder. Required when arrival = 'trace', "
        "refused otherwise.",
    )
    lateral: Literal["normal", "uniform"] = Field(
        "normal", description="Lateral placement: truncated normal or uniform across the belt."
    )
    lateral_mean: Real | None = num(
        None, "m", "Mean of the truncated normal in m; default the belt centre.", ge=0, le=10
    )
    lateral_sd: Real = num(
        0.08, "m", "SD of the truncated normal in m; at most the belt width.", gt=0, le=10
    )
    kinds: tuple[KindConfig, ...] = Field(
        (),
        max_length=64,
        description="Kinds of part ([[feeder.kinds]] name, share, value); default one kind. "
        "Drawn by share from their own stream, or named by a trace's kind column.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> FeederConfig:
        if self.kinds:
            names = [k.name for k in self.kinds]
            twice = next((n for i, n in enumerate(names) if n in names[:i]), None)
            if twice is not None:
                raise ValueError(
                    f"feeder.kinds.name: '{twice}' is given twice; name each kind once"
                )
            total = math.fsum(k.share for k in self.kinds)
            if abs(total - 1.0) > 1e-6:
                raise ValueError(
                    f"feeder.kinds.share: the shares sum to {total:g}; they must sum to 1 "
                    f"({' + '.join(f'{k.share:g}' for k in self.kinds)})"
                )
        if self.arrival == "trace" and not self.trace:
            raise ValueError("feeder.trace: a trace file is required when arrival = 'trace'")
        if self.arrival != "trace" and self.trace is not None:
            raise ValueError(
                f"feeder.trace: given, but feeder.arrival = '{self.arrival}' does not replay "
                "a trace; set feeder.arrival = 'trace', or remove feeder.trace"
            )
        if self.lateral == "uniform" and self.lateral_mean is not None:
            raise ValueError(
                "feeder.lateral_mean: given, but feeder.lateral = 'uniform' has no mean; "
                "set feeder.lateral = 'normal', or remove feeder.lateral_mean"
            )
        return self


Position = Annotated[Real, Field(ge=0, le=1000)]
PickTime = Annotated[Real, Field(ge=0, le=60)]
ArmSpeed = Annotated[Real, Field(gt=0, le=100), least(0.01, "m/s", "1 cm/s")]
Acceleration = Annotated[Real, Field(ge=0, le=1000)]
BinOffset = tuple[Annotated[Real, Field(ge=-10, le=10)], Annotated[Real, Field(ge=0, le=10)]]
Mtbf = Annotated[
    Real, Field(ge=0, le=1e9), least(0.1, "s", "10 breakdowns per second", zero_is_off=True)
]
Mttr = Annotated[Real, Field(ge=0, le=1e7)]
Side = Literal["upper", "lower", "over", "alternate"]
Reach = Annotated[Real, Field(ge=0, le=100)]
BaseOffset = Annotated[Real, Field(ge=0, le=10)]
Kinds = tuple[KindName, ...]
SIDES = ("upper", "lower", "over")


class RobotOverride(Frozen):
    """Per-robot overrides of the shared robot parameters; unset fields keep the default."""

    robot: Annotated[int, Strict(), Field(ge=1, le=64), INTEGRAL] = Field(
        description="Robot number, 1 = most upstream."
    )
    arm_speed: ArmSpeed | None = num(None, "m/s", "Tool speed v_r of this robot in m/s.")
    pick_time: PickTime | None = num(None, "s", "Grip time of this robot in s.")
    place_time: PickTime | None = num(None, "s", "Release time of this robot in s.")
    acceleration: Acceleration | None = num(None, "m/s^2", "Acceleration limit in m/s^2.")
    bin_offset: BinOffset | None = num(None, "m", "Bin position of this robot, as robots'.")
    mtbf: Mtbf | None = num(None, "s", "Mean time between failures of this robot in s.")
    mttr: Mttr | None = num(None, "s", "Mean time to repair of this robot in s.")
    side: Side | None = Field(
        None, description="Side of this robot: upper, lower, over (or alternate: by its number)."
    )
    reach: Reach | None = num(None, "m", "Reach of this robot from its base in m; 0: no limit.")
    base_offset: BaseOffset | None = num(
        None, "m", "Distance of this robot's base outward from its belt edge in m."
    )
    kinds: Kinds | None = Field(None, description="Kinds this robot picks; empty: all.")


class RobotsConfig(Frozen):
    """The robots, identical by default, upstream to downstream."""

    count: Annotated[int, Strict(), Field(ge=1, le=64), INTEGRAL] = Field(
        4, description="Number of robots N."
    )
    workspaces: tuple[tuple[Position, Position], ...] | None = num(
        None,
        "m",
        "Explicit workspaces [[a1, b1], ...] in m along the belt; when unset they "
        "are laid out from first_workspace_start, workspace_length and workspace_gap.",
    )
    first_workspace_start: Real = num(0.3, "m", "a_1 in m.", ge=0, le=1000)
    workspace_length: Annotated[Real, MIN_LENGTH] = num(
        0.2192, "m", "b_i - a_i in m.", gt=0, le=100
    )
    workspace_gap: Real = num(0.0, "m", "Gap between workspaces in m.", ge=0, le=100)
    arm_speed: ArmSpeed = num(3.0, "m/s", "Tool speed v_r in m/s (straight moves).")
    pick_time: PickTime = num(0.003694, "s", "Grip time in s.")
    place_time: PickTime = num(0.003694, "s", "Release time in s.")
    acceleration: Acceleration = num(
        0.0,
        "m/s^2",
        "Acceleration limit in m/s^2 (trapezoidal moves); 0 = instantaneous. When set, the "
        "arm must reach belt speed within its workspace: at least v_b^2 / (2 L_ws).",
    )
    bin_offset: BinOffset = num(
        (0.0, 0.5976),
        "m",
        "Bin position relative to (workspace centre x, upper belt edge W), in m; the bin "
        "sits on the upper side (second value >= 0).",
    )
    mtbf: Mtbf = num(0.0, "s", "Mean time between failures in s; 0 = no breakdowns.")
    mttr: Mttr = num(0.0, "s", "Mean time to repair in s.")
    failure_distribution: Literal["exponential", "fixed"] = Field(
        "exponential", description="Distribution of times between failures and to repair."
    )
    side: Side = Field(
        "upper",
        description="Where the robots stand: beside the belt on the upper side (y > W), the "
        "lower side (y < 0; the bin mirrored there), over the belt (base above its centre "
        "line; bin offset as given), or alternate (odd robots upper, even robots lower: facing "
        "pairs for any robot count). Workspaces are laid out back to back per side.",
    )
    reach: Reach = num(
        0.0,
        "m",
        "Reach in m: a part is a candidate only if its interception point lies within this "
        "distance of the robot's base (a disc for a delta robot); 0 = no limit.",
    )
    base_offset: BaseOffset = num(
        0.0,
        "m",
        "Distance of the base outward from the belt edge on the robot's side, in m (upper, "
        "lower); an 'over' robot's base is above the belt's centre line.",
    )
    kinds: Kinds = Field(
        (), description="Kinds of part the robots pick (feeder.kinds names); empty = all."
    )
    overrides: tuple[RobotOverride, ...] = Field(
        (),
        max_length=64,
        description="Per-robot overrides, e.g. [[robots.overrides]] robot = 2 arm_speed = 4.",
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

    def param(self, robot: int, name: str) -> Any:
        """Robot ``robot``'s (1-based) value of ``name``, its override if set (a side of
        "alternate" resolved: upper for odd robots, lower for even ones)."""
        value = getattr(self, name)
        for o in self.overrides:
            if o.robot == robot and getattr(o, name) is not None:
                value = getattr(o, name)
        if name == "side" and value == "alternate":
            return "upper" if robot % 2 else "lower"
        return value

    def sides(self, count: int | None = None) -> list[str]:
        """Each robot's side, robot 1 first (of the first ``count`` robots: a sizing study's
        count, robots past this line's count standing on the shared side)."""
        return [self.param(i, "side") for i in range(1, (count or self.count) + 1)]

    def deepest(self, count: int | None = None) -> int:
        """The most workspaces laid out back to back on one side (of ``count`` robots): how
        many workspace lengths of belt the robots need."""
        sides = self.sides(count)
        return max(sides.count(side) for side in SIDES)

    def layout(self) -> list[tuple[float, float]]:
        """Workspace bounds [a_i, b_i] in m (:func:`twin.geometry.workspaces`): explicit ones,
        or laid out back to back per side, in robot order (facing robots share x-ranges)."""
        if self.workspaces is not None:
            return workspaces(self.count, 0.0, 1.0, 0.0, self.workspaces)
        sides = self.sides()
        per_side = {
            side: iter(
                workspaces(
                    sides.count(side),
                    self.first_workspace_start,
                    self.workspace_length,
                    self.workspace_gap,
                )
            )
            for side in SIDES
        }
        return [next(per_side[side]) for side in sides]


class BinsConfig(Frozen):
    """Packaging boxes, one per robot."""

    capacity: Annotated[int, Strict(), Field(ge=0, le=1_000_000), INTEGRAL] = num(
        0, "parts", "Parts per box before a box change; 0 = unlimited."
    )
    change_time: Real = num(
        0.0, "s", "Box change time in s, during which the robot cannot place.", ge=0, le=3600
    )


Slot = tuple[Annotated[Real, Field(ge=-10, le=10)], Annotated[Real, Field(ge=-10, le=10)]]


class OutfeedConfig(Frozen):
    """A second conveyor the robots place onto instead of their bins: containers (trays)
    of ``slots`` carried at ``speed`` along x, co-flow (+x, like the infeed) or
    counter-flow (-x). A container's centre enters at the upstream end of the robots' span
    (co-flow: the smallest a_i) or at its downstream end (counter-flow: the largest b_i)."""

    speed: Annotated[Real, MIN_SPEED] = num(
        0.3, "m/s", "Outfeed speed in m/s (> 0; the direction says which way).", gt=0, le=10
    )
    direction: Literal["co", "counter"] = Field(
        "co", description="co: moves +x like the infeed; counter: moves -x."
    )
    pitch: Annotated[Real, MIN_LENGTH] | None = num(
        None, "m", "Distance between containers in m (give pitch or rate).", gt=0, le=100
    )
    rate: Annotated[Real, least(0.001, "containers/s", "one in 1000 s")] | None = num(
        None, "containers/s", "Containers per second on average (give pitch or rate).",
        gt=0, le=100,
    )  # fmt: skip
    arrival: Literal["fixed", "poisson", "normal"] = Field(
        "fixed",
        description="How containers arrive: fixed spacing (pitch, or 1/rate), Poisson, or "
        "normally distributed gaps (mean from pitch or rate, coefficient of variation cv), "
        "as the feeder's parts; a gap is never shorter than a container (they queue).",
    )
    cv: Real = num(
        0.3, "1", "Coefficient of variation of the gaps (arrival = normal).", ge=0, le=10
    )
    slots: tuple[Slot, ...] = Field(
        ((0.0, 0.0),),
        min_length=1,
        max_length=1000,
        description="Slots as [dx, dy] offsets in m from the container's centre (dx along "
        "the infeed's x, dy across), in the order slots are numbered.",
        json_schema_extra={"unit": "m"},
    )
    container_length: Annotated[Real, MIN_LENGTH] = num(
        0.3, "m", "Container length along the outfeed in m.", gt=0, le=100
    )
    container_width: Annotated[Real, MIN_LENGTH] = num(
        0.2, "m", "Container width across the outfeed in m.", gt=0, le=100
    )
    y: Annotated[Real, Field(ge=-100, le=100)] = num(
        0.8, "m", "The outfeed's centre line, y in the infeed's frame (m)."
    )

    @model_validator(mode="after")
    def _check(self) -> OutfeedConfig:
        if (self.pitch is None) == (self.rate is None):
            given = "both" if self.pitch is not None else "neither"
            raise ValueError(
                f"outfeed.pitch: {given} of outfeed.pitch and outfeed.rate given; give "
                "exactly one (pitch in m, or rate in containers/s)"
            )
        half_l, half_w = self.container_length / 2.0, self.container_width / 2.0
        for k, (dx, dy) in enumerate(self.slots, start=1):
            if abs(dx) > half_l + 1e-12 or abs(dy) > half_w + 1e-12:
                raise ValueError(
                    f"outfeed.slots: slot {k} [{dx:g}, {dy:g}] lies outside the "
                    f"{self.container_length:g} x {self.container_width:g} m container; "
                    f"allowed |dx| <= {half_l:g}, |dy| <= {half_w:g}"
                )
        if self.spacing < self.container_length - 1e-12:
            if self.pitch is not None:
                allowed = f"give a pitch of at least {self.container_length:g} m"
            else:
                most = self.speed / self.container_length
                allowed = f"give a rate of at most {most:.4g} containers/s (speed / length)"
            field = "pitch" if self.pitch is not None else "rate"
            raise ValueError(
                f"outfeed.{field}: containers {self.spacing:g} m apart are shorter than a "
                f"container (outfeed.container_length = {self.container_length:g} m); {allowed}"
            )
        return self

    @property
    def spacing(self) -> float:
        """Distance between containers' centres in m."""
        return self.pitch if self.pitch is not None else self.speed / float(self.rate or 1.0)

    @property
    def gap(self) -> float:
        """Time between containers entering, s."""
        return (
            self.spacing / self.speed if self.pitch is not None else 1.0 / float(self.rate or 1.0)
        )

    @property
    def min_gap(self) -> float:
        """The shortest time between containers entering: one container length, s."""
        return self.container_length / self.speed

    @property
    def sign(self) -> float:
        """+1.0 for co-flow, -1.0 for counter-flow: the outfeed's velocity is sign * speed."""
        return 1.0 if self.direction == "co" else -1.0


def policy_key(name: str) -> str:
    """A policy name as the registry reads it: rules upper-case, a prefix lower-case."""
    text = name.strip()
    prefix, sep, arg = text.partition(":")
    if sep:
        return f"{prefix.strip().lower()}:{arg.strip()}"
    return ",".join(r.strip().upper() for r in text.split(","))


def duplicate_policy(names: Any) -> str | None:
    """The first name in ``names`` that repeats an earlier one once normalised, else None."""
    seen: dict[str, str] = {}
    for name in names:
        key = policy_key(str(name))
        if key in seen:
            return f"'{name}' is '{seen[key]}' again"
        seen[key] = str(name)
    return None


def repeated_value(values: Any) -> Any | None:
    """A value that ``values`` (a grid's list) holds twice (``4`` and ``4.0`` are one value),
    or None: a repeated grid value would run the same point twice."""
    seen: list[Any] = []
    for v in values:
        if any(v == w and isinstance(v, bool) == isinstance(w, bool) for w in seen):
            return v
        seen.append(v)
    return None


class SweepConfig(Frozen):
    """A study: a grid over scenario fields, policies to compare, replications."""

    grid: dict[str, tuple[Any, ...]] = Field(
        default_factory=dict,
        description="Dotted scenario path -> list of values; the grid is their product.",
    )
    policies: tuple[Annotated[Text, Field(min_length=1, max_length=1000)], ...] = Field(
        (),
        description="Policies (names or per-robot mixes) to compare; default the scenario's. "
        "Each at most once (names are case-insensitive).",
    )
    replications: Annotated[int, Strict(), Field(ge=1, le=10_000), INTEGRAL] | Literal["auto"] = (
        Field(
            5,
            description="Replications per point and policy (2 or more for a CI), or 'auto': add "
            "replications in rounds until every point's CI half-width of G is at most half_width.",
        )
    )
    half_width: Annotated[Real, Field(gt=0, le=100), least(0.01, "%", "points of G")] | None = num(
        None, "%", "With replications = 'auto': the target CI half-width of G, in points."
    )
    max_replications: Annotated[int, Strict(), Field(ge=2, le=10_000), INTEGRAL] | None = Field(
        None, description="With replications = 'auto': the most replications (default 30)."
    )
    duration: Real | None = num(None, "s", "Overrides the run duration, s.", gt=0, le=YEAR)
    warmup: Real | None = num(None, "s", "Overrides the warm-up, s.", ge=0, le=YEAR)
    target: Real | None = num(
        None, "%", "Target gripping rate in percent, for sizing studies.", gt=0, le=100
    )

    @field_validator("grid")
    @classmethod
    def _grid_lists(cls, v: dict[str, tuple[Any, ...]]) -> dict[str, tuple[Any, ...]]:
        for path, values in v.items():
            if len(values) == 0:
                raise ValueError(f"sweep.grid.{path}: empty list; give at least one value")
            twice = repeated_value(values)
            if twice is not None:
                raise ValueError(
                    f"sweep.grid.{path}: {str(twice)[:40]} is given twice; give each value once "
                    "(a repeated value runs the same point twice)"
                )
        return v

    @field_validator("policies")
    @classmethod
    def _distinct(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        twice = duplicate_policy(v)
        if twice:
            raise ValueError(f"sweep.policies: {twice}; name each policy once")
        return v


Termination = Literal["t_continue", "t_all", "t_any"]


class Scenario(Frozen):
    """One line and one run: geometry, feeder, robots, bins, policy, timing, seed.

    ``source_dir`` (the scenario file's folder, against which a relative trace path is
    resolved) is not a field: the loader sets it, a user cannot (``--set source_dir=...``
    is an unknown key).
    """

    name: Text = Field(
        "scenario",
        min_length=1,
        max_length=200,
        pattern=NO_CONTROL,
        description="Short name, used in run and file names.",
    )
    description: Text = Field("", max_length=10_000, description="Free text shown in reports.")
    belt: BeltConfig = BeltConfig()
    feeder: FeederConfig = FeederConfig()
    robots: RobotsConfig = RobotsConfig()
    bins: BinsConfig = BinsConfig()
    outfeed: OutfeedConfig | None = Field(
        None, description="Optional outfeed conveyor the robots place onto (instead of bins)."
    )
    policy: Text = Field(
        "SD",
        min_length=1,
        max_length=1000,
        description="Rule name or per-robot mix, e.g. 'SPT,SPT,SPT,FIFO'.",
    )
    termination: Termination = Field("t_continue", description="t_continue | t_all | t_any.")
    duration: Real = num(
        600.0, "s", "Feeding time in s (the run then drains); at most a year.", gt=0, le=YEAR
    )
    warmup: Real = num(60.0, "s", "Parts fed before this time are not counted.", ge=0, le=YEAR)
    seed: Annotated[int, Strict(), Field(ge=0, le=SEED_MAX), INTEGRAL] = Field(
        1, description="Master seed of the run."
    )
    sweep: SweepConfig | None = Field(None, description="Optional study definition.")
    _source_dir: str | None = PrivateAttr(None)

    @property
    def source_dir(self) -> str | None:
        """Folder of the scenario file (set by the loader; resolves a relative trace path)."""
        return self._source_dir

    def located(self, source_dir: str | None) -> Scenario:
        """This scenario, read from a file in ``source_dir`` (a copy; the fields are equal)."""
        out = self.model_copy()
        out._source_dir = source_dir
        return out

    @model_validator(mode="after")
    def _check_line(self) -> Scenario:
        if self.warmup >= self.duration:
            raise ValueError(
                f"warmup: {self.warmup} s must be shorter than duration ({self.duration} s)"
            )
        self._check_layout()
        self._check_arms()
        self._check_kinds()
        self._check_reach()
        self._check_outfeed()
        f, w = self.feeder, self.belt.width
        if f.lateral_mean is not None and f.lateral_mean > w:
            raise ValueError(
                f"feeder.lateral_mean: {f.lateral_mean} m is off the belt; "
                f"allowed 0..{w} (belt.width)"
            )
        if f.lateral == "normal" and f.lateral_sd > w:
            raise ValueError(
                f"feeder.lateral_sd: {f.lateral_sd:g} m is wider than the belt "
                f"(belt.width = {w:g} m); give at most {w:g} m, or feeder.lateral = 'uniform'"
            )
        if self.robots.mtbf > 0 and self.robots.mttr <= 0:
            raise ValueError("robots.mttr: must be > 0 when robots.mtbf > 0 (breakdowns on)")
        for i in range(1, self.robots.count + 1):
            if self.robot_param(i, "mtbf") > 0 and self.robot_param(i, "mttr") <= 0:
                raise ValueError(
                    f"robots.overrides: robot {i} breaks down (mtbf > 0) with no repair time; "
                    "give it mttr > 0 (in its override or in robots.mttr)"
                )
        return self

    def _check_layout(self) -> None:
        spaces = self.robots.layout()
        sides = self.robots.sides()
        prev: dict[str, tuple[int, float]] = {}  # side -> (robot, end) of its last workspace
        one_side = len(set(sides)) == 1
        for i, ((a, b), side) in enumerate(zip(spaces, sides, strict=True), start=1):
            if not 0 <= a < b:
                raise ValueError(f"robots.workspaces: robot {i} has [{a}, {b}]; need 0 <= a < b")
            j, prev_b = prev.get(side, (0, -math.inf))
            if a < prev_b:
                where = "" if one_side else f" on the {side} side"
                raise ValueError(
                    f"robots.workspaces: robot {i} starts at {a} m inside robot {j}'s "
                    f"workspace (ends {prev_b} m){where}; workspaces must not overlap, "
                    "upstream first" + ("" if one_side else " on each side")
                )
            prev[side] = (i, b)
        last = max(b for _, b in spaces)
        if last > self.belt.length + 1e-9:
            raise ValueError(
                f"robots.workspaces: the last workspace ends at {last:g} m, beyond "
                f"belt.length = {self.belt.length:g} m; lengthen the belt or shrink workspaces"
            )

    def _check_arms(self) -> None:
        v_b = self.belt.speed
        for i, (a, b) in enumerate(self.robots.layout(), start=1):
            v_r = self.robot_param(i, "arm_speed")
            if v_r <= v_b:
                raise ValueError(
                    f"robots.arm_speed: {v_r:g} m/s for robot {i} must exceed belt.speed "
                    f"({v_b:g} m/s) or no part can be intercepted"
                )
            acc = self.robot_param(i, "acceleration")
            least = v_b * v_b / (2.0 * (b - a))
            if 0 < acc <= least:
                raise ValueError(
                    f"robots.acceleration: {acc:g} m/s^2 for robot {i} is too low to reach "
                    f"belt speed ({v_b:g} m/s) within its {b - a:g} m workspace; give more "
                    f"than {least:.3g} m/s^2, or 0 for no limit"
                )

    def _check_kinds(self) -> None:
        known = {k.name for k in self.feeder.kinds}
        for i in range(1, self.robots.count + 1):
            for kind in self.robot_param(i, "kinds"):
                if kind not in known:
                    allowed = ", ".join(sorted(known)) if known else "none: feeder.kinds is empty"
                    raise ValueError(
                        f"robots.kinds: robot {i} picks '{kind}', which is not a kind of "
                        f"feeder.kinds; allowed {allowed}"
                    )

    def _check_reach(self) -> None:
        w = self.belt.width
        for i, (a, b) in enumerate(self.robots.layout(), start=1):
            reach = self.robot_param(i, "reach")
            side = self.robot_param(i, "side")
            if reach <= 0:
                continue
            offset = self.robot_param(i, "base_offset")
            base = mount_position((a, b), w, side, offset)
            gap = 0.0 if side == "over" else offset
            if reach <= gap:
                raise ValueError(
                    f"robots.reach: {reach:g} m for robot {i} does not touch the belt (its "
                    f"base is {offset:g} m beyond the {side} edge); give more than {gap:g} m, "
                    "or 0 for no limit"
                )
            if self.outfeed is not None:
                continue  # robots place onto the outfeed: their bins are not used
            bx, by = bin_position((a, b), w, self.robot_param(i, "bin_offset"), side)
            far = math.hypot(bx - base[0], by - base[1])
            if far > reach + 1e-9:
                raise ValueError(
                    f"robots.reach: {reach:g} m for robot {i} does not reach its bin "
                    f"({far:.3g} m from its base); give at least {far:.3g} m, move the bin "
                    "(bin_offset), or 0 for no limit"
                )

    def _check_outfeed(self) -> None:
        out = self.outfeed
        if out is None:
            return
        if self.bins.capacity or self.bins.change_time:
            raise ValueError(
                "bins: capacity and change_time do not apply with [outfeed] (robots place "
                "onto the outfeed, not into boxes); remove them"
            )
        w = self.belt.width
        reachable = False
        for i, (a, b) in enumerate(self.robots.layout(), start=1):
            v_r = self.robot_param(i, "arm_speed")
            if v_r <= out.speed:
                raise ValueError(
                    f"outfeed.speed: {out.speed:g} m/s is not below robot {i}'s arm_speed "
                    f"({v_r:g} m/s), so no slot can be intercepted; give less than {v_r:g} m/s"
                )
            reach = self.robot_param(i, "reach")
            side, offset = self.robot_param(i, "side"), self.robot_param(i, "base_offset")
            my = mount_position((a, b), w, side, offset)[1]
            if reach <= 0 or abs(out.y - my) <= reach:
                reachable = True
        if not reachable:
            raise ValueError(
                f"outfeed.y: no robot reaches an outfeed at y = {out.y:g} m (robots.reach "
                "from each robot's base); move the outfeed nearer the robots, or give them "
                "more reach"
            )

    def robot_param(self, robot: int, name: str) -> Any:
        """Robot ``robot``'s (1-based) value of ``name``, its override if set."""
        return self.robots.param(robot, name)

    def kind_names(self) -> tuple[str, ...]:
        """The kinds of part, in the order feeder.kinds gives them ("" alone: one kind)."""
        return tuple(k.name for k in self.feeder.kinds) or ("",)
