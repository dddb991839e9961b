"""A line as arrays: the scenario, streams and policy turned into the kernel's inputs.

:class:`FastLine` mirrors :class:`twin.line.Line`: the same seed split (feeder arrivals,
lateral positions, policy, one stream per robot), the same feeder stream, the same derived
constants (computed here in Python with the twin's own expressions, so they are the same
doubles). Random draws the SimPy run makes during the run are pre-drawn: SIRO's
``Generator.integers`` as the policy stream's raw ``next_uint32`` outputs (the kernel
replays numpy's Lemire rejection), breakdowns as standard exponentials (``exponential(m)``
is ``m * standard_exponential()``). Before an event that could run out of a stream or of
the span buffer, the kernel stops (ST_ROOM) and the line grows it in place (streams draw on
from their generators) and carries on, so the result never depends on the first guess.

A policy that is a Python object (the learned HDQN, any ``choose``) runs through a callback:
its robots carry the rule code EXTERNAL, the kernel stops at each of their decisions
(ST_CHOOSE) and :meth:`FastLine.run` hands the policy the same :class:`~twin.decision.Decision`
the SimPy gateway builds, then resumes with its answer. ``hold=True`` pauses at every
decision epoch instead (ST_EPOCH), as the SimPy gateway's hold mode does for environments.
"""

from __future__ import annotations

import copy
import math
from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np

from pnp_twin.twin.decision import Decision, Policy, RobotSpec, fixed_rules
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.belt_view import BeltView
from pnp_twin.twin.fast.kernel import (
    choose_external,
    close_open_spans,
    release,
    run_events,
    start_robots,
)
from pnp_twin.twin.feeder import Feeder
from pnp_twin.twin.kpis import SPAN_STATES, PartRecords, SpanRecords
from pnp_twin.twin.line import DRAIN_SLACK, robot_specs
from pnp_twin.twin.records import Recorder
from pnp_twin.twin.scenario import Scenario


class Unsupported(ValueError):
    """The fast engine cannot run this line as asked; the message says why."""


def rule_codes(policy: Policy, n_robots: int) -> list[int] | None:
    """Per-robot rule codes of a policy that picks by fixed built-in rules (after its reset:
    :func:`~pnp_twin.twin.decision.fixed_rules`), None if it names other rules or another
    robot count, or chooses otherwise."""
    rules = fixed_rules(policy) or []
    if len(rules) != n_robots or any(r not in L.RULE_NAMES[:-1] for r in rules):
        return None
    return [L.RULE_NAMES.index(r) for r in rules]


def _robot_params(scenario: Scenario, specs: list[RobotSpec]) -> tuple[np.ndarray, np.ndarray]:
    fp = np.zeros((len(specs), L.N_FP))
    ip = np.zeros((len(specs), L.N_IP), dtype=np.int64)
    width = scenario.belt.width
    for spec in specs:
        r = spec.index
        a, b = spec.workspace
        # as Robot.__init__ computes them
        xs = (a, b, spec.bin[0])
        ys = (0.0, width, spec.bin[1])
        reach = math.hypot(max(xs) - min(xs), max(ys) - min(ys))
        fp[r, L.BA], fp[r, L.BB] = a, b
        fp[r, L.XLO] = a - reach * spec.belt_speed / spec.arm_speed
        fp[r, L.QUAD] = spec.arm_speed**2 - spec.belt_speed**2
        fp[r, L.VR], fp[r, L.ACC] = spec.arm_speed, spec.acceleration
        fp[r, L.PICK], fp[r, L.PLACE] = spec.pick_time, spec.place_time
        fp[r, L.BX], fp[r, L.BY] = spec.bin
        fp[r, L.BASEX], fp[r, L.BASEY] = (a + b) / 2.0, width / 2.0
        mtbf = scenario.robot_param(r + 1, "mtbf")
        mttr = scenario.robot_param(r + 1, "mttr")
        fp[r, L.MTBF], fp[r, L.MTTR] = mtbf, mttr
        if mtbf > 0:
            fixed = scenario.robots.failure_distribution == "fixed"
            ip[r, L.FAILMODE] = L.FIXED if fixed else L.EXPONENTIAL
    return fp, ip


STATE = (
    "ip", "fs", "ist", "gs", "gf", "holder", "left_at", "rec_i", "rec_f", "sp_i", "sp_f",
    "counts", "_c_i", "_c_f",
)  # fmt: skip
"""The arrays a run changes as it goes (``ip``'s rule codes in hold mode; the rest is
parameters and pre-drawn streams, which only grow by new arrays)."""


class FastLine:
    """One run of one scenario with any policy, as arrays; :meth:`run` fills the records."""

    sp_i: np.ndarray  # the span buffer (set by start, grown by _grow)
    sp_f: np.ndarray

    def __init__(
        self,
        scenario: Scenario,
        policy: Policy | None = None,
        seed: int | None = None,
        duration: float | None = None,
        rules: Sequence[str] | None = None,
        hold: bool = False,
    ) -> None:
        """``policy`` is any policy: a rule mix (policies.base.RuleMix) is compiled, reset
        here as Line resets it; any other is called back at its decisions (reset and attached
        at each :meth:`start`). Or give ``rules`` (one name, or one per robot) and no policy.
        ``hold`` pauses at every decision epoch (see :meth:`release`)."""
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else seed
        self.duration = scenario.duration if duration is None else duration
        n = scenario.robots.count
        children = np.random.SeedSequence(self.seed).spawn(3 + n)
        streams = [np.random.default_rng(s) for s in children]
        b = scenario.belt
        feeder = Feeder(scenario.feeder, b.width, streams[0], streams[1], scenario.source_dir)
        self.fed, self.y, self.kind = feeder.stream(self.duration)
        self.fed = np.ascontiguousarray(self.fed, dtype=np.float64)
        self.y = np.ascontiguousarray(self.y, dtype=np.float64)
        self.specs = robot_specs(scenario)
        self.external: Policy | None = None
        self._policy_seed = children[2]
        self.extra_rules: list[str] = []  # rule names of external choices beyond RULE_NAMES
        self.extra_counts: Counter[tuple[int, str]] = Counter()
        if policy is not None:
            codes = None
            if hasattr(policy, "fixed_rules"):
                policy.reset(self.specs, streams[2])  # as Line resets it (a mix of one widens)
                codes = rule_codes(policy, n)
            if codes is None:
                self.external = policy
                codes = [L.EXTERNAL] * n
        else:
            names = [r.upper() for r in rules or ["FIFO"]]
            bad = [r for r in names if r not in L.RULE_NAMES[:-1]]
            if bad or len(names) not in (1, n):
                raise Unsupported(
                    f"rules: {','.join(names)} is not one rule or one per robot ({n}) of "
                    f"{', '.join(L.RULE_NAMES[:-1])}"
                )
            codes = [L.RULE_NAMES.index(r) for r in (names * n if len(names) == 1 else names)]
        self.policy = policy
        self.policy_rng = streams[2]
        self.failure_rngs = streams[3:]
        self.fp, self.ip = _robot_params(scenario, self.specs)
        self.ip[:, L.RULE] = codes
        self.gp = np.zeros(L.N_GP)
        self.gp[L.V] = b.speed
        self.gp[L.TICK] = (b.length / b.grid[0]) / b.speed
        self.last_end = self.specs[-1].workspace[1]
        change = scenario.bins.change_time
        self.end_at = self.duration + self.last_end / b.speed + DRAIN_SLACK + change
        self.gp[L.END_AT] = self.end_at
        self.gp[L.CHANGE] = change
        self.gp[L.HALF], self.gp[L.TWO] = 0.5, 2.0
        self.gi = np.zeros(L.N_GI, dtype=np.int64)
        self.gi[L.SCHEME] = L.SCHEME_CODES[scenario.termination]
        self.gi[L.CAPACITY] = scenario.bins.capacity
        self.gi[L.HOLD] = int(hold)
        self.uses_siro = L.SIRO in codes
        self.breaks = bool(self.ip[:, L.FAILMODE].any())

    # -- streams ---------------------------------------------------------------------------
    def _streams(self, siro_room: int, exp_room: int) -> None:
        """Pre-drawn draws from fresh copies of the policy and failure streams (the copies
        are kept: :meth:`_grow` draws on from them)."""
        self._siro_rng = copy.deepcopy(self.policy_rng)
        self._exp_rngs = [copy.deepcopy(rng) for rng in self.failure_rngs]
        self._siro = self._draw_siro(siro_room if self.uses_siro else 0)
        self._exps = self._draw_exps(exp_room if self.breaks else 0)

    def _draw_siro(self, k: int) -> np.ndarray:
        return self._siro_rng.integers(0, 2**32, size=k, dtype=np.uint32).astype(np.int64)

    def _draw_exps(self, k: int) -> np.ndarray:
        exps = np.zeros((len(self.specs), k))
        for r, rng in enumerate(self._exp_rngs):
            if self.ip[r, L.FAILMODE] == L.EXPONENTIAL:
                exps[r] = rng.standard_exponential(k)
        return exps

    def _grow(self) -> None:
        """ST_ROOM: double what the kernel is short of. Streams go on drawing from their
        generators, so the result never depends on the first guess of the room."""
        what = int(self.gs[L.ROOMFOR])
        if what == L.ROOM_SPANS:
            self.sp_i = np.concatenate([self.sp_i, np.zeros_like(self.sp_i)])
            self.sp_f = np.concatenate([self.sp_f, np.zeros_like(self.sp_f)])
        elif what == L.ROOM_SIRO:
            self._siro = np.concatenate([self._siro, self._draw_siro(max(len(self._siro), 64))])
        else:
            more = self._draw_exps(max(self._exps.shape[1], 64))
            self._exps = np.concatenate([self._exps, more], axis=1)
        self.gs[L.STATUS] = L.ST_OK

    def run(self) -> None:
        """Feed for ``duration`` seconds, then drain (as Line.run)."""
        if self.gi[L.HOLD]:
            raise ValueError("run: a line in hold mode is driven by advance() and release()")
        self.start(*self._rooms())
        status = self.advance(self.end_at)
        while status == L.ST_CHOOSE:
            self.answer()
            status = self.advance(self.end_at)
        if status == L.ST_OK:
            status = self.finish()
        if status != L.ST_OK:  # the margins the kernel keeps make this unreachable
            raise RuntimeError(f"engine fast: an event ran out of room (status {status})")

    def _rooms(self) -> tuple[int, int, int]:
        """First guesses of the span buffer and the pre-drawn SIRO and failure streams."""
        n_parts, n = len(self.fed), len(self.specs)
        mtbf = self.fp[:, L.MTBF]
        mean = float(mtbf[mtbf > 0].min()) if self.breaks else 1.0
        # a NooP lasts a belt tick or until the next part enters: at most one per tick or part
        spans = n * (int(self.end_at / self.gp[L.TICK]) + n_parts + 2) + 4 * n_parts + 1024
        return spans, 2 * n_parts + 1024, int(4 * self.end_at / mean) + 64

    def start(self, span_room: int, siro_room: int, exp_room: int) -> None:
        """The state at t = 0: robots at their bases, processes about to start."""
        n_parts = len(self.fed)
        n = len(self.specs)
        self._streams(siro_room, exp_room)
        self.fs = np.zeros((n, L.N_FS))
        self.ist = np.zeros((n, L.N_IS), dtype=np.int64)
        self.gs = np.zeros(L.N_GS, dtype=np.int64)
        self.gf = np.zeros(1)
        self.holder = np.full(n_parts, -1, dtype=np.int64)
        self.left_at = np.full(n_parts, math.inf)
        self.rec_i = np.full((n_parts, 2), -1, dtype=np.int64)
        self.rec_f = np.full((n_parts, 4), math.nan)
        self.rec_f[:, 3] = 0.0
        self.sp_i = np.zeros((span_room, 2), dtype=np.int64)
        self.sp_f = np.zeros((span_room, 2))
        self.counts = np.zeros((n, len(L.RULE_NAMES)), dtype=np.int64)
        self._c_i = np.zeros(n_parts + 1, dtype=np.int64)
        self._c_f = np.zeros((n_parts + 1, 3))
        start_robots(self.fp, self.ip, self.fs, self.ist, self.gs, self._exps)
        self.extra_rules, self.extra_counts = [], Counter()
        if self.external is not None:  # as Line: reset with the policy stream, then attach
            self.external.reset(self.specs, np.random.default_rng(self._policy_seed))
            attach = getattr(self.external, "attach", None)
            if callable(attach):
                attach(self.belt)

    def advance(self, until: float) -> int:
        """Process every event before ``until`` (growing buffers and streams as needed); the
        status: 0 (reached ``until``), ST_CHOOSE (an external policy's decision: call
        :meth:`answer`) or ST_EPOCH (hold mode: call :meth:`release`)."""
        while True:
            status = run_events(
                self.fp, self.ip, self.gp, self.gi, self.fs, self.ist, self.gs, self.gf,
                self.fed, self.y, self.holder, self.left_at, self.rec_i, self.rec_f,
                self.sp_i, self.sp_f, self.counts, self._siro, self._exps, self._c_i,
                self._c_f, min(until, self.end_at),
            )  # fmt: skip
            if status != L.ST_ROOM:
                return int(status)
            self._grow()

    def answer(self) -> None:
        """Ask the external policy about the decision the kernel stopped at (ST_CHOOSE)."""
        assert self.external is not None
        r, n = int(self.gs[L.DROBOT]), int(self.gs[L.DN])
        c_f = self._c_f
        d = Decision(
            self.specs[r],
            float(self.fs[r, L.T0]),
            (float(self.fs[r, L.TOOLX]), float(self.fs[r, L.TOOLY])),
            self._c_i[:n].tolist(),
            c_f[:n, 0].tolist(),
            c_f[:n, 1].tolist(),
            c_f[:n, 2].tolist(),
        )
        k = self.external.choose(d)
        if k < 0 or k >= n:  # as Gateway.choose
            raise IndexError(
                f"policy {type(self.external).__name__} chose candidate {k} of {n} for robot {r}"
            )
        rule = getattr(self.external, "last_rule", None)
        self.extra_counts[(r, rule or "?")] += 1
        choose_external(
            self.fp, self.gp, self.fs, self.ist, self.gs, self.holder, self.left_at,
            self._c_i, self._c_f, k, self._code(rule),
        )  # fmt: skip

    def _code(self, rule: str | None) -> int:
        """The rule code recorded with a pick: RULE_NAMES' index, or an extra name's."""
        if rule is None:
            return L.NO_RULE
        if rule in L.RULE_NAMES[:-1]:
            return L.RULE_NAMES.index(rule)
        if rule not in self.extra_rules:
            self.extra_rules.append(rule)
        return len(L.RULE_NAMES) + self.extra_rules.index(rule)

    # -- hold mode -------------------------------------------------------------------------
    def pending(self) -> list[int]:
        """The robots of the decision epoch the kernel paused at (hold mode, ST_EPOCH)."""
        return [int(r) for r in np.flatnonzero(self.ist[:, L.PENDING])]

    def release(self, rules: Sequence[int] | None = None) -> None:
        """Gateway.release: set each robot's rule code (when given), resume the pending ones."""
        if rules is not None:
            self.ip[:, L.RULE] = rules
        release(self.fs, self.ist, self.gs, self.gf[L.NOW])

    def finish(self) -> int:
        """End the run at ``end_at`` (after :meth:`advance` to it): open spans are closed."""
        n_spans, room = int(self.gs[L.NSPANS]), len(self.sp_i)
        if room and n_spans + len(self.specs) > room:  # one more span per robot at most
            self.gs[L.ROOMFOR] = L.ROOM_SPANS
            self._grow()
        status = close_open_spans(self.ist, self.fs, self.gs, self.sp_i, self.sp_f, self.end_at)
        self.gf[L.NOW] = self.end_at
        return int(status)

    def fork(self) -> FastLine:
        """An independent copy of the run as it stands: its state arrays, counts and the
        generators its streams grow from are copied. An external policy is not: answering
        a fork's decision asks the same policy object."""
        other = copy.copy(self)
        for name in STATE:
            setattr(other, name, getattr(self, name).copy())
        other.extra_rules, other.extra_counts = list(self.extra_rules), Counter(self.extra_counts)
        other._siro_rng = copy.deepcopy(self._siro_rng)
        other._exp_rngs = copy.deepcopy(self._exp_rngs)
        return other

    # -- records ---------------------------------------------------------------------------
    def kpi_records(self) -> tuple[PartRecords, SpanRecords]:
        """The run's records as :func:`twin.kpis.compute_kpis` reads them, from the arrays."""
        k = int(self.gs[L.NSPANS])
        codes = np.array([SPAN_STATES.index(s) for s in L.SPAN_NAMES], dtype=np.int64)
        parts = PartRecords(
            fed_at=self.fed,
            robot=self.rec_i[:, 0],
            rule=self.rec_i[:, 1],  # a code of rule_names; -1 where not picked or unnamed
            rule_names=(*L.RULE_NAMES, *self.extra_rules),
            decided_at=self.rec_f[:, 0],
            placed_at=self.rec_f[:, 2],
            picked=~np.isnan(self.rec_f[:, 1]),
        )
        spans = SpanRecords(
            robot=self.sp_i[:k, 0],
            state=codes[self.sp_i[:k, 1]],
            start=self.sp_f[:k, 0],
            end=self.sp_f[:k, 1],
        )
        return parts, spans

    def recorder(self) -> Recorder:
        """The run's records in the twin's Recorder, so tables are built by the same code."""
        rec = Recorder(len(self.fed))  # defaults for every list, then the run's values
        # arrays where Recorder keeps lists: its tables read them with np.asarray / np.where
        rec.robot = self.rec_i[:, 0]  # type: ignore[assignment]
        names = np.array([*L.RULE_NAMES, *self.extra_rules, None], dtype=object)
        rec.rule = names[self.rec_i[:, 1]].tolist()  # code -1 (not picked, no name) -> None
        rec.decided_at = self.rec_f[:, 0]  # type: ignore[assignment]
        rec.picked_at = self.rec_f[:, 1]  # type: ignore[assignment]
        rec.placed_at = self.rec_f[:, 2]  # type: ignore[assignment]
        rec.blocked = self.rec_f[:, 3]  # type: ignore[assignment]
        k = int(self.gs[L.NSPANS])
        states = [L.SPAN_NAMES[s] for s in self.sp_i[:k, 1].tolist()]
        rec.spans = list(
            zip(self.sp_i[:k, 0].tolist(), states, *self.sp_f[:k].T.tolist(), strict=True)
        )
        counts: Counter[tuple[int, str]] = Counter()
        for r, c in zip(*np.nonzero(self.counts), strict=True):
            counts[(int(r), L.RULE_NAMES[c])] = int(self.counts[r, c])
        rec.decisions = counts + self.extra_counts
        return rec

    @property
    def belt(self) -> Any:
        """The belt as policies, cameras and Recorder.parts_frame read it: a
        :class:`~twin.fast.belt_view.BeltView` (a twin.belt.Belt to them, live over the arrays)."""
        b = self.scenario.belt
        arrays = (self.fed, self.y, self.holder, self.left_at)
        return BeltView(
            b.length, b.width, b.speed, b.grid, self.last_end, arrays, self.kind, self.gf
        )

    @property
    def now(self) -> float:
        return float(self.gf[L.NOW])
