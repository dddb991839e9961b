"""One description of a line: everything derived from a scenario, computed once.

Both engines read a :class:`LinePlan`: the SimPy twin (:class:`twin.line.Line` hands each
:class:`~twin.robot.Robot` its :class:`RobotPlan`) and the compiled engine
(:class:`twin.fast.engine.FastLine` turns the same plan into the kernel's arrays). So the
derived constants (workspaces and bins, each robot's reach margin ``x_lo``, its base, the
belt tick, the end of the run, the seed split, the rule and scheme codes) are the same
doubles in both, written once here.

The seed is split into independent child streams, in this order: feeder arrivals, lateral
positions, the policy, one per robot (breakdowns), then the parts' kinds, the robots'
priority order (ties between facing robots) and the outfeed's container arrivals; so the
part stream does not depend on the policy, and a line of one kind on one side draws exactly
what it drew before kinds existed.
:meth:`LinePlan.seeds` gives the children; a stream's generator is built only where a run
uses it (:meth:`LinePlan.stream`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.gateway import SCHEMES
from pnp_twin.twin.geometry import bin_position, intercept_quad, mount_position
from pnp_twin.twin.kpis import KindTable
from pnp_twin.twin.outfeed import OutfeedPlan
from pnp_twin.twin.scenario import Scenario

RULES = ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT", "VAL")
"""The built-in dispatching rules; a rule's code is its index here (both engines)."""
# SCHEMES (imported above, from the gateway that runs them): a scheme's code is its index
DRAIN_SLACK = 30.0  # s after the last part passed the last workspace, for the last places
ARRIVALS, LATERAL, POLICY, FIRST_ROBOT = range(4)
"""The seed split: child stream k of the master seed (robot r's is ``FIRST_ROBOT + r``)."""
__all__ = [
    "ARRIVALS", "DRAIN_SLACK", "FIRST_ROBOT", "LATERAL", "POLICY", "RULES", "SCHEMES",
    "LinePlan", "RobotPlan", "overlap", "reach_margin", "robot_specs", "rivals",
]  # fmt: skip


def robot_specs(scenario: Scenario) -> list[RobotSpec]:
    """Each robot's resolved parameters (shared defaults with per-robot overrides)."""
    out = []
    belt = scenario.belt
    kinds = scenario.feeder.kinds
    names = [k.name for k in kinds]
    for i, (a, b) in enumerate(scenario.robots.layout()):
        p = lambda name, i=i: scenario.robot_param(i + 1, name)  # noqa: E731
        side = p("side")
        pick, place = float(p("pick_time")), float(p("place_time"))
        mine = set(p("kinds"))
        out.append(
            RobotSpec(
                index=i,
                count=scenario.robots.count,
                workspace=(a, b),
                bin=bin_position((a, b), belt.width, p("bin_offset"), side),
                arm_speed=float(p("arm_speed")),
                acceleration=float(p("acceleration")),
                pick_time=pick,
                place_time=place,
                belt_speed=belt.speed,
                belt_width=belt.width,
                side=side,
                reach=float(p("reach")),
                mount=mount_position((a, b), belt.width, side, float(p("base_offset"))),
                picks=tuple(not mine or n in mine for n in names),
                pick_times=tuple(pick if k.pick_time is None else k.pick_time for k in kinds),
                place_times=tuple(place if k.place_time is None else k.place_time for k in kinds),
                values=tuple(k.value for k in kinds),
            )
        )
    return out


def overlap(a: RobotSpec, b: RobotSpec) -> bool:
    """Whether two robots' x-ranges overlap (more than touch)."""
    return a.workspace[0] < b.workspace[1] and b.workspace[0] < a.workspace[1]


def rivals(specs: list[RobotSpec]) -> bool:
    """Whether two robots' x-ranges overlap (facing robots): then a part several idle robots
    could take is offered only to the one that intercepts it soonest (see twin.robot)."""
    return any(overlap(a, b) for i, a in enumerate(specs) for b in specs[i + 1 :])


def reach_margin(spec: RobotSpec, place_ys: tuple[float, ...] = ()) -> float:
    """``x_lo``: upstream parts can only be intercepted inside [a, b] when the tool is far
    from them; beyond this margin the tool always meets them before x = a. ``place_ys``:
    where else across the belt the tool may stand (an outfeed's slots, placed inside [a, b])."""
    a, b = spec.workspace
    xs = (a, b, spec.bin[0])
    ys = (0.0, spec.belt_width, spec.bin[1], *place_ys)
    reach = math.hypot(max(xs) - min(xs), max(ys) - min(ys))
    return a - reach * spec.belt_speed / spec.arm_speed


@dataclass(frozen=True)
class RobotPlan:
    """One robot as both engines run it."""

    spec: RobotSpec
    x_lo: float  # reach margin (:func:`reach_margin`)
    quad: float  # v_r^2 - v_b^2 (:func:`twin.geometry.intercept_quad`)
    base: tuple[float, float]  # the tool's position at t = 0: workspace centre, belt centre
    mtbf: float  # s; 0: no breakdowns
    mttr: float  # s
    failures: str  # "exponential" or "fixed" (read when mtbf > 0)
    priority: int = 0  # rank among facing robots on an exact tie (lower first)

    @property
    def breaks(self) -> bool:
        return self.mtbf > 0


@dataclass(frozen=True)
class LinePlan:
    """One run's line: the scenario with a seed and a feeding duration, and all that
    follows from them (see the module docstring)."""

    scenario: Scenario
    seed: int
    duration: float  # s of feeding
    robots: tuple[RobotPlan, ...]
    last_end: float  # m: the end of the last workspace
    tick: float  # s: the time the belt needs to move one grid cell (the longest NooP)
    end_at: float  # s: the end of the run (feeding, then the drain)
    scheme: int  # code of the termination scheme (index into SCHEMES)
    capacity: int  # parts per box, 0: unlimited
    change_time: float  # s per box change
    kinds: tuple[str, ...] = ("",)  # the kinds of part, by code ("" alone: one kind)
    shares: tuple[float, ...] = (1.0,)  # each kind's share of the flow
    values: tuple[float, ...] = (1.0,)  # each kind's value per part
    targeted: tuple[bool, ...] = (True,)  # each kind: some robot picks it
    rivals: bool = False  # some robots' x-ranges overlap (facing robots compete)
    outfeed: OutfeedPlan | None = None  # robots place onto an outfeed (None: into bins)

    @classmethod
    def of(
        cls, scenario: Scenario, seed: int | None = None, duration: float | None = None
    ) -> LinePlan:
        """The plan of a run of ``scenario`` (its own seed and duration unless given)."""
        seed = scenario.seed if seed is None else seed
        duration = scenario.duration if duration is None else duration
        b = scenario.belt
        robots = []
        specs = robot_specs(scenario)
        facing = rivals(specs)
        out = scenario.outfeed
        place_ys: tuple[float, ...] = ()
        if out is not None:
            place_ys = tuple(out.y + dy for _, dy in out.slots)
        order = [0] * len(specs)
        if facing:  # ties between facing robots: a random order, not the robots' numbers
            seeds = np.random.SeedSequence(seed).spawn(FIRST_ROBOT + len(specs) + 2)
            order = np.random.default_rng(seeds[-1]).permutation(len(specs)).tolist()
        for spec in specs:
            a, end = spec.workspace
            i = spec.index + 1
            robots.append(
                RobotPlan(
                    spec=spec,
                    x_lo=reach_margin(spec, place_ys),
                    quad=intercept_quad(spec.arm_speed, spec.belt_speed),
                    base=((a + end) / 2.0, b.width / 2.0),
                    mtbf=scenario.robot_param(i, "mtbf"),
                    mttr=scenario.robot_param(i, "mttr"),
                    failures=scenario.robots.failure_distribution,
                    priority=int(order[spec.index]),
                )
            )
        last_end = max(r.spec.workspace[1] for r in robots)
        kinds = scenario.feeder.kinds
        change = scenario.bins.change_time
        end_at = duration + last_end / b.speed + DRAIN_SLACK + change
        outfeed = None
        if out is not None:  # containers drawn from their own stream, after the robots' order
            rng = None
            if out.arrival != "fixed":
                stream = np.random.SeedSequence(seed).spawn(FIRST_ROBOT + len(specs) + 3)[-1]
                rng = np.random.default_rng(stream)
            outfeed = OutfeedPlan.of(out, specs, end_at, rng)
        return cls(
            scenario=scenario,
            seed=seed,
            duration=duration,
            robots=tuple(robots),
            last_end=last_end,
            tick=(b.length / b.grid[0]) / b.speed,
            end_at=end_at,
            scheme=SCHEMES.index(scenario.termination),
            capacity=scenario.bins.capacity,
            change_time=change,
            kinds=scenario.kind_names(),
            shares=tuple(k.share for k in kinds) or (1.0,),
            values=tuple(k.value for k in kinds) or (1.0,),
            targeted=tuple(any(s.picks[c] for s in specs) for c in range(len(kinds))) or (True,),
            rivals=facing,
            outfeed=outfeed,
        )

    @property
    def specs(self) -> list[RobotSpec]:
        return [r.spec for r in self.robots]

    def kind_codes(self, kinds: list[str] | None, n: int) -> np.ndarray:
        """Each part's kind code (its index in :attr:`kinds`) from the stream's kind names;
        all 0 on a line of one kind (a trace's kind column is then free text)."""
        if kinds is None or len(self.kinds) == 1:
            return np.zeros(n, dtype=np.int64)
        code = {name: c for c, name in enumerate(self.kinds)}
        return np.array(list(map(code.__getitem__, kinds)), dtype=np.int64)

    def kind_table(self) -> KindTable | None:
        """The kinds of part as the KPIs read them; None on a line without feeder.kinds."""
        if not self.scenario.feeder.kinds:
            return None
        return KindTable(self.kinds, self.values, self.targeted)

    def new_shape(self) -> str | None:
        """The first setting beyond the paper's line shape (one kind, one side, no reach
        limit, bins rather than an outfeed), or None: what the engines support but some
        tools (vector envs, rollouts) refuse."""
        sc = self.scenario
        if sc.outfeed is not None:
            return "outfeed"
        if sc.feeder.kinds:
            return "feeder.kinds"
        for name, plain in (("side", "upper"), ("reach", 0.0), ("kinds", ())):
            if any(sc.robot_param(i, name) != plain for i in range(1, len(self.robots) + 1)):
                return f"robots.{name}"
        return None

    @property
    def kinds_stream(self) -> int:
        """The child stream the parts' kinds are drawn from (after the robots')."""
        return FIRST_ROBOT + len(self.robots)

    def seeds(self) -> list[np.random.SeedSequence]:
        """The child seeds of the split (see the module docstring)."""
        return np.random.SeedSequence(self.seed).spawn(FIRST_ROBOT + len(self.robots) + 3)

    @staticmethod
    def stream(seeds: list[np.random.SeedSequence], k: int) -> np.random.Generator:
        """The generator of child stream ``k`` (ARRIVALS, LATERAL, POLICY, FIRST_ROBOT + r)."""
        return np.random.default_rng(seeds[k])

    def streams(self) -> list[np.random.Generator]:
        """Every child stream's generator, in the split's order."""
        return [np.random.default_rng(s) for s in self.seeds()]
