"""A line as arrays: the scenario, streams and policy turned into the kernel's inputs.

:class:`FastLine` mirrors :class:`twin.line.Line`: both read the run's
:class:`~twin.plan.LinePlan` (the seed split, the derived constants: the same doubles), and
the same feeder stream. A stream's generator is built only where the run uses it (the
policy's for a rule mix or SIRO, a robot's when it breaks down exponentially), and copied
only for SIRO. Random draws the SimPy run makes during the run are pre-drawn: SIRO's
``Generator.integers`` as the policy stream's raw ``next_uint32`` outputs (the kernel
replays numpy's Lemire rejection), breakdowns as standard exponentials (``exponential(m)``
is ``m * standard_exponential()``). Before an event that could run out of a stream or of
the span buffer, the kernel stops (ST_ROOM) and the line grows it in place (streams draw on
from their generators) and carries on, so the result never depends on the first guess: the
guesses are sized from the run (about a span per part, and the robots' NooPs while the line
drains), not for the worst case.

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
from dataclasses import replace
from typing import Any

import numpy as np

from pnp_twin.twin.decision import Decision, Policy, fixed_rules
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.belt_view import BeltView
from pnp_twin.twin.fast.kernel import (
    choose_external,
    close_open_spans,
    decline_external,
    release,
    run_events,
    start_robots,
)
from pnp_twin.twin.fast.pool import take
from pnp_twin.twin.fast.structs import Params, Records, Scratch, State, Streams
from pnp_twin.twin.feeder import Feeder
from pnp_twin.twin.kpis import SPAN_STATES, PartRecords, SpanRecords, compute_kpis, tally_kpis
from pnp_twin.twin.plan import ARRIVALS, FIRST_ROBOT, LATERAL, POLICY, LinePlan, overlap
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


def _robot_params(plan: LinePlan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel's robot parameters: the plan's robots as rows of arrays (``kp``: per
    robot and kind code)."""
    fp = np.zeros((len(plan.robots), L.N_FP))
    ip = np.zeros((len(plan.robots), L.N_IP), dtype=np.int64)
    kp = np.zeros((len(plan.robots), len(plan.kinds), L.N_KP))
    for r, rp in enumerate(plan.robots):
        spec = rp.spec
        fp[r, L.BA], fp[r, L.BB] = spec.workspace
        fp[r, L.XLO] = rp.x_lo
        fp[r, L.QUAD] = rp.quad
        fp[r, L.VR], fp[r, L.ACC] = spec.arm_speed, spec.acceleration
        fp[r, L.PICK], fp[r, L.PLACE] = spec.pick_time, spec.place_time
        fp[r, L.BX], fp[r, L.BY] = spec.bin
        fp[r, L.BASEX], fp[r, L.BASEY] = rp.base
        fp[r, L.MTBF], fp[r, L.MTTR] = rp.mtbf, rp.mttr
        if rp.breaks:
            ip[r, L.FAILMODE] = L.FIXED if rp.failures == "fixed" else L.EXPONENTIAL
        fp[r, L.REACH] = spec.reach
        fp[r, L.MOUNTX], fp[r, L.MOUNTY] = spec.mount
        fp[r, L.BINSIDE] = spec.bin_side
        ip[r, L.PRIO] = rp.priority
        facing = any(overlap(spec, o.spec) for o in plan.robots if o is not rp)
        ip[r, L.FILTER] = (spec.reach > 0 or not all(spec.picks)) * L.TESTS + facing * L.RIVALS
        for k in range(len(plan.kinds)):
            kp[r, k] = (
                1.0 if not spec.picks or spec.picks[k] else 0.0,
                spec.pick_of(k),
                spec.place_of(k),
                spec.value_of(k),
            )
    return fp, ip, kp


def _outfeed_params(plan: LinePlan) -> np.ndarray:
    """The kernel's outfeed parameters ``og`` (see layout): the plan's outfeed, its robots'
    place intervals and its containers' entry times, or ``og[OUT_ON] = 0`` on a line with
    bins."""
    out = plan.outfeed
    if out is None:
        return np.zeros(L.N_OG)
    orb = np.stack([np.array(out.lo), np.array(out.hi), np.array(out.entry)], axis=-1)
    times = np.asarray(out.times, dtype=np.float64)
    head = np.zeros(L.N_OG)
    head[L.OUT_ON], head[L.OUT_U], head[L.OUT_GAP] = 1.0, out.u, out.gap
    head[L.OUT_XIN], head[L.OUT_Y], head[L.OUT_NS] = out.x_in, out.y, out.n_slots
    slots = np.column_stack([out.dx, out.dy]).ravel()
    head[L.OUT_ORB] = L.N_OG + len(slots)
    head[L.OUT_TIMES] = head[L.OUT_ORB] + orb.size
    head[L.OUT_NT] = len(times)
    return np.concatenate([head, slots, orb.ravel(), times])


STATE = ("ip", *State._fields, *Records._fields, "_c_i", "_c_f")
"""The arrays a run changes as it goes (``ip``'s rule codes in hold mode; the rest is
parameters and pre-drawn streams, which only grow by new arrays)."""


def _longer(a: np.ndarray, rows: int) -> np.ndarray:
    """A copy of ``a`` with ``rows`` rows, the new ones zero."""
    out = np.zeros((rows, *a.shape[1:]), dtype=a.dtype)
    out[: len(a)] = a
    return out


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
        self.plan = plan = LinePlan.of(scenario, seed, duration)
        self.seed = plan.seed
        self.duration = plan.duration
        n = len(plan.robots)
        seeds = plan.seeds()  # generators are built only for the streams this run uses
        b = scenario.belt
        arrivals, lateral = plan.stream(seeds, ARRIVALS), plan.stream(seeds, LATERAL)
        kinds = plan.stream(seeds, plan.kinds_stream) if scenario.feeder.kinds else None
        feeder = Feeder(scenario.feeder, b.width, arrivals, lateral, scenario.source_dir, kinds)
        self.fed, self.y, self.kind = feeder.stream(self.duration)
        self.fed = np.ascontiguousarray(self.fed, dtype=np.float64)
        self.y = np.ascontiguousarray(self.y, dtype=np.float64)
        drawn = feeder.codes  # drawn kinds come with their codes; a trace's are looked up
        self.kind_code = plan.kind_codes(self.kind, len(self.fed)) if drawn is None else drawn
        self.specs = plan.specs
        self.external: Policy | None = None
        self._seeds = seeds
        self._policy_seed = seeds[POLICY]
        self.extra_rules: list[str] = []  # rule names of external choices beyond RULE_NAMES
        self.extra_counts: Counter[tuple[int, str]] = Counter()
        self.policy_rng: np.random.Generator | None = None
        if policy is not None:
            codes = None
            if hasattr(policy, "fixed_rules"):
                self.policy_rng = plan.stream(seeds, POLICY)
                policy.reset(self.specs, self.policy_rng)  # as Line resets it
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
        self.fp, self.ip, self.kp = _robot_params(plan)
        self.ip[:, L.RULE] = codes
        self.gp = np.zeros(L.N_GP)
        self.gp[L.V] = b.speed
        self.gp[L.TICK] = plan.tick
        self.last_end = plan.last_end
        self.end_at = plan.end_at
        self.gp[L.END_AT] = self.end_at
        self.gp[L.CHANGE] = plan.change_time
        self.gp[L.HALF], self.gp[L.TWO] = 0.5, 2.0
        self.gi = np.zeros(L.N_GI, dtype=np.int64)
        self.gi[L.SCHEME] = plan.scheme
        self.gi[L.CAPACITY] = plan.capacity
        self.gi[L.HOLD] = int(hold)
        self.og = _outfeed_params(plan)
        self.uses_siro = L.SIRO in codes
        self.breaks = bool(self.ip[:, L.FAILMODE].any())

    # -- streams ---------------------------------------------------------------------------
    def _streams(self, siro_room: int, exp_room: int) -> None:
        """Pre-drawn draws of the streams this run uses: SIRO's from a copy of the policy
        stream as the policy holds it, breakdowns' from fresh generators of the robots'
        streams. The generators are kept: :meth:`_grow` draws on from them."""
        self._siro_rng: np.random.Generator | None = None
        self._exp_rngs: list[np.random.Generator | None] = [None] * len(self.specs)
        if self.uses_siro:  # a rule mix's reset was given policy_rng: copy it as it stands
            rng = self.policy_rng
            fresh = rng is None
            self._siro_rng = self.plan.stream(self._seeds, POLICY) if fresh else copy.deepcopy(rng)
        for r in np.flatnonzero(self.ip[:, L.FAILMODE] == L.EXPONENTIAL).tolist():
            self._exp_rngs[r] = self.plan.stream(self._seeds, FIRST_ROBOT + r)
        self._siro = self._draw_siro(siro_room if self.uses_siro else 0)
        self._exps = self._draw_exps(exp_room if self.breaks else 0)

    def _draw_siro(self, k: int) -> np.ndarray:
        if self._siro_rng is None:
            return np.zeros(0, dtype=np.int64)
        return self._siro_rng.integers(0, 2**32, size=k, dtype=np.uint32).astype(np.int64)

    def _draw_exps(self, k: int) -> np.ndarray:
        exps = np.zeros((len(self.specs), k))
        for r, rng in enumerate(self._exp_rngs):
            if rng is not None:
                exps[r] = rng.standard_exponential(k)
        return exps

    def _grow(self) -> None:
        """ST_ROOM: double what the kernel is short of. Streams go on drawing from their
        generators, so the result never depends on the first guess of the room."""
        what = int(self.gs[L.ROOMFOR])
        if what == L.ROOM_SPANS:
            rows = self._span_room()
            # in place (a reallocation: never the old and the new buffer at once), unless
            # something else holds a view of a buffer: then a longer copy
            try:
                self.sp_i.resize((rows, 2), refcheck=True)
            except ValueError:
                self.sp_i = _longer(self.sp_i, rows)
            try:
                self.sp_f.resize((rows, 2), refcheck=True)
            except ValueError:
                self.sp_f = _longer(self.sp_f, rows)
        elif what == L.ROOM_SIRO:
            self._siro = np.concatenate([self._siro, self._draw_siro(max(len(self._siro), 64))])
        else:
            more = self._draw_exps(max(self._exps.shape[1], 64))
            self._exps = np.concatenate([self._exps, more], axis=1)
        self.gs[L.STATUS] = L.ST_OK

    def _span_room(self) -> int:
        """The span buffer's new length when it is full: the spans so far projected to the
        end of the run at the rate so far, and 5 % more (1.5 to 8 times the buffer)."""
        k, now, room = int(self.gs[L.NSPANS]), max(self.now, self.gp[L.TICK]), len(self.sp_i)
        projected = int(1.05 * k * (self.end_at / now)) + len(self.specs) + 2 * L.SPAN_MARGIN
        return max(min(projected, 8 * room), int(1.5 * room) + 64)

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
        """First guesses of the span buffer and the pre-drawn SIRO and failure streams; all
        grow on demand (ST_ROOM), so a guess only sets the memory and the number of calls.
        Spans: about one per part, and each robot's NooPs during the drain."""
        n_parts, n = len(self.fed), len(self.specs)
        mtbf = self.fp[:, L.MTBF]
        mean = float(mtbf[mtbf > 0].min()) if self.breaks else 1.0
        drain = int((self.end_at - self.duration) / self.gp[L.TICK]) + 2
        spans = n_parts + n * drain + 256
        return spans, n_parts + 256, int(4 * self.end_at / mean) + 64

    def start(self, span_room: int, siro_room: int, exp_room: int) -> None:
        """The state at t = 0: robots at their bases, processes about to start."""
        n_parts = len(self.fed)
        n = len(self.specs)
        self._streams(siro_room, exp_room)
        more = len(self.plan.kinds) - 1  # a bin per kind: columns beyond the layout's
        self.fs = np.zeros((n, L.N_FS + more))
        self.ist = np.zeros((n, L.N_IS + more), dtype=np.int64)
        self.gs = np.zeros(L.N_GS, dtype=np.int64)
        self.gf = np.zeros(1)
        # the large arrays in memory earlier runs let go (twin.fast.pool), set as new ones
        self.holder = take("holder", n_parts, np.int64)
        self.holder.fill(-1)
        self.left_at = take("left_at", n_parts)
        self.left_at.fill(math.inf)
        out = self.plan.outfeed  # with an outfeed: container, slot; held at, hold time
        self.rec_i = take("rec_i", (n_parts, 2 if out is None else 4), np.int64)
        self.rec_i.fill(-1)
        self.rec_f = take("rec_f", (n_parts, 4 if out is None else 6))
        self.rec_f.fill(math.nan)  # not decided, picked, placed; blocked 0 s
        self.rec_f[:, 3] = 0.0  # (a fill and a column: a fifth of a row-tuple's assignment)
        containers = int(self.og[L.OUT_NT]) if self.plan.outfeed is not None else 0
        self.taken = np.zeros((containers, 0 if out is None else out.n_slots), dtype=np.int64)
        if out is not None:
            self.rec_f[:, 5] = 0.0
        # the span buffer owns its memory: it grows in place (ndarray.resize)
        self.sp_i = np.zeros((span_room, 2), dtype=np.int32)  # robot, state
        self.sp_f = np.zeros((span_room, 2))  # start, end
        self.counts = np.zeros((n, len(L.RULE_NAMES)), dtype=np.int64)
        self._c_i = take("c_i", n_parts + 1, np.int64)  # scratch: a decision's candidates
        self._c_f = take("c_f", (n_parts + 1, 3))
        start_robots(self.params, self.state, self.streams)
        self.extra_rules, self.extra_counts = [], Counter()
        if self.external is not None:  # as Line: reset with the policy stream, then attach
            self.external.reset(self.specs, np.random.default_rng(self._policy_seed))
            bind = getattr(self.external, "bind_run", None)
            if callable(bind):
                bind(self.scenario, self.seed, self.duration)
            attach = getattr(self.external, "attach", None)
            if callable(attach):
                attach(self.belt)

    def advance(self, until: float) -> int:
        """Process every event before ``until`` (growing buffers and streams as needed); the
        status: 0 (reached ``until``), ST_CHOOSE (an external policy's decision: call
        :meth:`answer`) or ST_EPOCH (hold mode: call :meth:`release`)."""
        while True:
            # the structures live only through the call: _grow resizes the span buffer in
            # place only when nothing else refers to it
            status = run_events(*self.structs, min(until, self.end_at))
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
            self.kind_code[self._c_i[:n]].tolist(),
        )
        k = self.external.choose(d)
        if k is None:  # as Robot.working: the policy picks nothing now, a NooP
            decline_external(self.params, self.state, self.streams)
            return
        if k < 0 or k >= n:  # as Gateway.choose
            raise IndexError(
                f"policy {type(self.external).__name__} chose candidate {k} of {n} for robot {r}"
            )
        rule = getattr(self.external, "last_rule", None)
        self.extra_counts[(r, rule or "?")] += 1
        choose_external(self.params, self.state, self.streams, self.scratch, k, self._code(rule))

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
        release(self.state)

    def finish(self) -> int:
        """End the run at ``end_at`` (after :meth:`advance` to it): open spans are closed."""
        n_spans, room = int(self.gs[L.NSPANS]), len(self.sp_i)
        if room and n_spans + len(self.specs) > room:  # one more span per robot at most
            self.gs[L.ROOMFOR] = L.ROOM_SPANS
            self._grow()
        status = close_open_spans(self.state, self.records, self.end_at)
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

    # -- the kernel's structures (views of the arrays above, built for each call) ----------
    @property
    def params(self) -> Params:
        return Params(self.fp, self.ip, self.gp, self.gi, self.kp, self.og)

    @property
    def state(self) -> State:
        return State(
            self.fs, self.ist, self.gs, self.gf, self.holder, self.left_at, self.counts, self.taken
        )

    @property
    def records(self) -> Records:
        return Records(self.rec_i, self.rec_f, self.sp_i, self.sp_f)

    @property
    def streams(self) -> Streams:
        return Streams(self.fed, self.y, self._siro, self._exps, self.kind_code)

    @property
    def scratch(self) -> Scratch:
        return Scratch(self._c_i, self._c_f)

    @property
    def structs(self) -> tuple[Params, State, Records, Streams, Scratch]:
        """All five, in the order the kernel takes them."""
        return self.params, self.state, self.records, self.streams, self.scratch

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
        kinds = self.plan.kind_table()
        if kinds is not None:
            parts = kinds.with_records(parts, self.kind_code)
        if self.plan.outfeed is not None:
            parts = replace(parts, container=self.rec_i[:, 2], held_at=self.rec_f[:, 4])
        spans = SpanRecords(
            robot=self.sp_i[:k, 0],
            state=codes[self.sp_i[:k, 1]],
            start=self.sp_f[:k, 0],
            end=self.sp_f[:k, 1],
        )
        return parts, spans

    def kpis(self, warmup: float) -> dict[str, Any]:
        """The run's KPIs, as :func:`twin.kpis.compute_kpis` gives them from
        :meth:`kpi_records`, with the sums taken in one compiled pass over the arrays."""
        from pnp_twin.twin.fast.tally import tally

        kinds, out = self.plan.kind_table(), self.plan.outfeed
        if kinds is not None or out is not None:  # kinds, an outfeed: the numpy sums
            parts, spans = self.kpi_records()
            return compute_kpis(parts, spans, self.specs, warmup, self.duration, kinds, out)
        names = (*L.RULE_NAMES, *self.extra_rules)
        n_spans, n = int(self.gs[L.NSPANS]), len(self.specs)
        sums = tally(self.fed, self.records, n_spans, n, len(names), warmup, self.duration)
        return tally_kpis(sums, names, self.specs, warmup, self.duration)

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
        if self.plan.outfeed is not None:
            rec.outfeed = True
            rec.container = self.rec_i[:, 2]  # type: ignore[assignment]
            rec.slot = self.rec_i[:, 3]  # type: ignore[assignment]
            rec.held_at = self.rec_f[:, 4]  # type: ignore[assignment]
            rec.hold_time = self.rec_f[:, 5]  # type: ignore[assignment]
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
