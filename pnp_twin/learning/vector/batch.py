"""Many runs of one scenario in hold mode, as batched arrays (the vector environment's state).

:class:`LineBatch` holds :class:`~pnp_twin.twin.fast.engine.FastLine`'s arrays with a leading
line axis and steps them all with :func:`pnp_twin.learning.vector.step.step_lines`.
:meth:`LineBatch.load` gives line e a fresh run of a seed (the same seed split, part stream
and pre-drawn streams as ``FastLine(scenario, seed=seed)``). The pre-drawn SIRO draws and
breakdown exponentials are topped up from the run's own generators before a step whenever
fewer than a safe margin remain (numpy draws the same numbers in two calls as in one), so a
long episode never runs out; should a line still run dry, :meth:`LineBatch.step` raises one
clear line.

**Threads.** A step runs its lines in chunks on numba's threads and returns when the
slowest thread is done: on a machine whose cores are busy with other work, a second thread
that gets no core makes the whole step wait for it (and spins meanwhile). Measured side by
side, interleaved, on the project's 2-core machine shared with other jobs (load average 13,
``python bench/bench_vector_threads.py --envs 8,32,128,512 --rounds 5 --steps 8000``), two
threads gave 0.04x, 0.13x, 0.07x and 0.41x the env steps per wall second of one thread for
8, 32, 128 and 512 lines (and 4 to 25x fewer per CPU second); on the same machine idle they
gave 1.4x at 1,024 lines (README). So a batch uses :data:`DEFAULT_THREADS` (one) unless
``threads`` asks for more: give ``threads=2`` (or more) only on cores that are yours, with a
few hundred lines or more.

**First compile.** The first step in a process with no cached machine code for the step
(a fresh checkout, or any change to this folder's or the engine's sources) compiles it:
about a minute of CPU. :func:`compile_notice` then warns once (:class:`CompileNotice`,
a ``UserWarning`` Python shows on stderr) when the compile starts; a step read from
numba's on-disk cache warns nothing.
"""

from __future__ import annotations

import math
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import replace

import numba
import numpy as np
from numba.core import event as numba_event

from pnp_twin.learning.vector import step as V
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.fast.engine import FastLine
from pnp_twin.twin.fast.structs import Params, Records, Scratch, State, Streams
from pnp_twin.twin.feeder import Feeder
from pnp_twin.twin.plan import ARRIVALS, FIRST_ROBOT, LATERAL, POLICY, LinePlan
from pnp_twin.twin.scenario import Scenario

SIRO_ROOM, SIRO_MARGIN = 2048, 256
"""Pre-drawn SIRO draws per line; topped up when fewer than the margin remain (a step
draws about one per deciding robot)."""
EXP_ROOM, EXP_MARGIN = 64, 16
"""Pre-drawn breakdown exponentials per robot; a step draws at most a few per robot."""
PARTS_SLACK, PARTS_PAD = 1.25, 256
"""Room for parts per line: this much more than the stream at hand (grown when needed)."""
DEFAULT_THREADS = 1
"""numba threads per step unless asked (see the module docstring: never slower than two)."""


COMPILE_NOTICE = (
    "pnp_twin: compiling the vector env's step (about a minute of CPU, once per change of "
    "the code; later runs read numba's on-disk cache)"
)


Structs = tuple[Params, V.EnvParams, State, Streams, Records, Scratch, V.Episodes, V.StepOut]
"""What :func:`~pnp_twin.learning.vector.step.step_lines` takes before the codes and modes."""


class StreamsExhausted(RuntimeError):
    """A line used up its pre-drawn random draws within one step (never expected)."""


class CompileNotice(UserWarning):
    """numba is compiling (not reading from its cache) code the user waits for."""


class _CompileListener(numba_event.Listener):
    """Warns once, when the first compile of the block starts."""

    def __init__(self, message: str) -> None:
        self.message = message
        self.warned = False

    def on_start(self, event: numba_event.Event) -> None:
        if not self.warned:
            self.warned = True
            warnings.warn(self.message, CompileNotice, stacklevel=_user_level())

    def on_end(self, event: numba_event.Event) -> None:
        """Nothing at the end."""


_OURS = ("numba", "pnp_twin", "gymnasium", "pettingzoo", "contextlib", "importlib")


def _user_level() -> int:
    """The ``stacklevel`` of the first frame outside numba, pnp_twin and the env libraries,
    so the notice names the user's line that stepped the env, not numba's internals."""
    frame, level = sys._getframe(1), 1
    while frame.f_back is not None and str(frame.f_globals.get("__name__", "")).startswith(_OURS):
        frame, level = frame.f_back, level + 1
    return level


@contextmanager
def compile_notice(message: str = COMPILE_NOTICE) -> Iterator[_CompileListener]:
    """Within the block, warn ``message`` once (:class:`CompileNotice`) if numba compiles
    anything: its ``numba:compile`` event, which a load from the on-disk cache never fires."""
    listener = _CompileListener(message)
    with numba_event.install_listener("numba:compile", listener):
        yield listener


class LineBatch:
    """``n`` runs of ``scenario`` in hold mode, one row of every state array per run.

    ``params`` fills :data:`pnp_twin.learning.vector.step.N_EF` episode floats (see the
    column names there), ``max_steps`` the step cap (0: none); ``channels`` the
    observation's channels; ``skip_noops`` runs past epochs where no deciding robot has a
    candidate; ``threads`` the numba threads a step uses (None: :data:`DEFAULT_THREADS`).
    """

    def __init__(
        self,
        scenario: Scenario,
        n: int,
        channels: int,
        params: dict[int, float],
        max_steps: int,
        siro: bool,
        skip_noops: bool = False,
        threads: int | None = None,
    ) -> None:
        self.scenario = scenario
        self.n = n
        shape = LinePlan.of(scenario).new_shape()
        if shape is not None:
            raise ValueError(
                f"{shape}: the vector environments run lines of one kind of part with every "
                "robot on the upper side, no reach limit and bins (no outfeed); use the "
                "Gymnasium or PettingZoo environment (one line) for this scenario"
            )
        template = FastLine(scenario, rules=["FIFO"], hold=True)
        self.plan = template.plan
        self.fp, self.ip0, self.gp, self.gi = template.fp, template.ip, template.gp, template.gi
        self.kp, self.og = template.kp, template.og
        self.n_robots = r = len(template.specs)
        self.siro = siro
        self.breaks = template.breaks
        camera = BeltCamera(scenario, channels)
        self.shape = camera.shape
        self.spans = np.array(camera.spans, dtype=np.int64).reshape(r, 2)
        b = scenario.belt
        self.ef = np.zeros(V.N_EF)
        for col, value in params.items():
            self.ef[col] = value
        self.ef[V.BELT_LAG] = b.length / b.speed  # as Belt.on_belt
        self.ef[V.END_LAG] = template.last_end / b.speed  # as Belt.passed
        self.ef[V.COL_SCALE] = camera.nx / camera.length
        self.ef[V.ROW_SCALE] = camera.ny / camera.width
        self.ef[V.SPEED] = b.speed
        self.ef[V.WARMUP] = scenario.warmup
        self.ei = np.zeros(V.N_EI, dtype=np.int64)
        self.ei[V.MAX_STEPS] = max_steps
        self.ei[V.SKIP_NOOPS] = int(skip_noops)
        top = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
        if threads is None:
            threads = DEFAULT_THREADS
        if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= top:
            raise ValueError(f"threads: {threads!r} is not allowed; give 1 to {top}")
        self.threads = threads
        self.n_chunks = min(n, 4 * threads) if threads > 1 else 1
        self._loaded = False  # whether this batch has stepped (the step compiled)
        self._alloc(int(len(template.fed) * PARTS_SLACK) + PARTS_PAD)
        self._policy_rngs: list[np.random.Generator | None] = [None] * n
        self._failure_rngs: list[list[np.random.Generator]] = [[] for _ in range(n)]

    def _alloc(self, parts: int) -> None:
        n, r = self.n, self.n_robots
        self._built: Structs | None = None
        self.parts = parts
        self.ip = np.repeat(self.ip0[None], n, axis=0)
        self.fs = np.zeros((n, r, L.N_FS))
        self.ist = np.zeros((n, r, L.N_IS), dtype=np.int64)
        self.gs = np.zeros((n, L.N_GS), dtype=np.int64)
        self.gf = np.zeros((n, 1))
        self.fed = np.full((n, parts), math.inf)
        self.ys = np.zeros((n, parts))
        self.kind = np.zeros((n, parts), dtype=np.int64)  # one kind: every code 0
        self.holder = np.full((n, parts), -1, dtype=np.int64)
        self.left_at = np.full((n, parts), math.inf)
        self.counts = np.zeros((n, r, len(L.RULE_NAMES)), dtype=np.int64)
        self.taken = np.zeros((n, 0, 0), dtype=np.int64)  # no outfeed (refused above)
        self.siro_draws = np.zeros((n, SIRO_ROOM if self.siro else 0), dtype=np.int64)
        self.exps = np.zeros((n, r, EXP_ROOM if self.breaks else 0))
        self.started = np.full((n, r), math.nan)
        self.noops0 = np.zeros((n, r), dtype=np.int64)
        self.epi = np.zeros((n, V.N_EPI), dtype=np.int64)
        self._scratch(parts)
        self.obs = np.zeros((n, *self.shape), dtype=np.uint8)
        self.reward = np.zeros(n)
        self.term = np.zeros(n, dtype=np.bool_)
        self.trunc = np.zeros(n, dtype=np.bool_)
        self.tau = np.zeros(n)
        self.grip = np.zeros(n)
        self.picks = np.zeros((n, r), dtype=np.int64)
        self.noops = np.zeros((n, r), dtype=np.int64)
        self.rewards = np.zeros((n, r))
        self.options = np.zeros((n, r))
        self.cand = np.zeros((n, r), dtype=np.int64)
        self.skipped = np.zeros(n, dtype=np.int64)

    def _scratch(self, parts: int) -> None:
        """Per-chunk arrays the kernel writes and no environment reads (and no spans)."""
        c = self.n_chunks
        self._built = None
        self.rec_i = np.full((c, parts, 2), -1, dtype=np.int64)
        self.rec_f = np.zeros((c, parts, 4))
        self.sp_i = np.zeros((c, 0, 2), dtype=np.int64)
        self.sp_f = np.zeros((c, 0, 2))
        self.c_i = np.zeros((c, parts + 1), dtype=np.int64)
        self.c_f = np.zeros((c, parts + 1, 3))

    def _grow(self, parts: int) -> None:
        """Room for ``parts`` parts per line, the lines' parts kept."""
        old = self.parts
        grown = (("fed", math.inf), ("ys", 0.0), ("kind", 0), ("holder", -1), ("left_at", math.inf))
        for name, fill in grown:
            a = getattr(self, name)
            b = np.full((self.n, parts), fill, dtype=a.dtype)
            b[:, :old] = a
            setattr(self, name, b)
        self.parts = parts
        self._scratch(parts)

    # -- runs ------------------------------------------------------------------------------
    def load(self, e: int, seed: int) -> None:
        """Line e's next run is a fresh one of ``seed`` (it starts at the next step)."""
        sc = self.scenario
        seeds = replace(self.plan, seed=seed).seeds()  # the core's seed split
        streams = [LinePlan.stream(seeds, k) for k in range(len(seeds))]
        feeder = Feeder(
            sc.feeder, sc.belt.width, streams[ARRIVALS], streams[LATERAL], sc.source_dir
        )
        fed, y, _ = feeder.stream(sc.duration)
        m = len(fed)
        if m > self.parts:
            self._grow(max(m, int(m * PARTS_SLACK) + PARTS_PAD))
        self.fed[e, :m] = fed
        self.fed[e, m:] = math.inf
        self.ys[e, :m] = y
        self.gs[e, L.SIROIDX] = 0  # the new streams are unused: no top-up before the start
        self.ist[e, :, L.EXPIDX] = 0
        if self.siro:
            policy = streams[POLICY]
            self._policy_rngs[e] = policy
            self.siro_draws[e] = policy.integers(0, 2**32, size=SIRO_ROOM, dtype=np.uint32)
        if self.breaks:
            robots = streams[FIRST_ROBOT : FIRST_ROBOT + self.n_robots]
            self._failure_rngs[e] = robots
            for r, rng in enumerate(robots):
                if self.ip0[r, L.FAILMODE] == L.EXPONENTIAL:
                    self.exps[e, r] = rng.standard_exponential(EXP_ROOM)

    def top_up(self) -> None:
        """Refill the pre-drawn streams of the lines with fewer than a margin left: the
        kernel stops (ST_ROOM) before an event with less than its own margin left, and a
        step draws at most one SIRO number per robot and two exponentials per robot."""
        siro_margin = max(SIRO_MARGIN, L.SIRO_MARGIN + self.n_robots)
        exp_margin = max(EXP_MARGIN, L.EXP_MARGIN + 2)
        if self.siro:
            for e in np.flatnonzero(self.gs[:, L.SIROIDX] > SIRO_ROOM - siro_margin).tolist():
                k = int(self.gs[e, L.SIROIDX])
                row = self.siro_draws[e]
                row[: SIRO_ROOM - k] = row[k:]
                rng = self._policy_rngs[e]
                assert rng is not None
                row[SIRO_ROOM - k :] = rng.integers(0, 2**32, size=k, dtype=np.uint32)
                self.gs[e, L.SIROIDX] = 0
        if self.breaks:
            low = self.ist[:, :, L.EXPIDX] > EXP_ROOM - exp_margin
            for e, r in zip(*np.nonzero(low), strict=True):
                k = int(self.ist[e, r, L.EXPIDX])
                row = self.exps[e, r]
                row[: EXP_ROOM - k] = row[k:]
                row[EXP_ROOM - k :] = self._failure_rngs[e][r].standard_exponential(k)
                self.ist[e, r, L.EXPIDX] = 0

    def step(self, codes: np.ndarray, mode: np.ndarray) -> None:
        """Step each line as ``mode`` (int8, n) says (:data:`~pnp_twin.learning.vector.step.SKIP`,
        ACT, RESET: start its loaded run); ACT answers its epoch with the rule codes
        ``codes`` (n, robots). Each line stepped then runs to its next decision epoch."""
        self.top_up()
        numba.set_num_threads(self.threads)
        structs = self._structs()
        if self._loaded:  # compiled: skip asking numba (its signatures list costs 12 us)
            V.step_lines(*structs, codes, mode)
        else:  # this batch's first step: maybe the process's first, which compiles or loads
            with compile_notice() if not V.step_lines.signatures else nullcontext():
                V.step_lines(*structs, codes, mode)
            self._loaded = True
        if not V.statuses_ok(self.gs):
            bad = int(np.flatnonzero(self.gs[:, L.STATUS] != L.ST_EPOCH)[0])
            status = int(self.gs[bad, L.STATUS])
            raise StreamsExhausted(
                f"engine fast: line {bad} stopped with status {status} (a pre-drawn stream "
                "ran out within one step); raise SIRO_ROOM/EXP_ROOM in "
                "pnp_twin.learning.vector.batch"
            )

    def _structs(self) -> Structs:
        """The arrays as :func:`~pnp_twin.learning.vector.step.step_lines` takes them, built
        once per allocation (:meth:`_alloc`, :meth:`_grow` set new arrays and drop them)."""
        if self._built is None:
            self._built = self._build_structs()
        return self._built

    def _build_structs(self) -> Structs:
        return (
            Params(self.fp, self.ip, self.gp, self.gi, self.kp, self.og),
            V.EnvParams(self.ef, self.ei, self.spans, self.ip0),
            State(*(getattr(self, name) for name in State._fields)),
            Streams(self.fed, self.ys, self.siro_draws, self.exps, self.kind),
            Records(*(getattr(self, name) for name in Records._fields)),
            Scratch(self.c_i, self.c_f),
            V.Episodes(*(getattr(self, name) for name in V.Episodes._fields)),
            V.StepOut(*(getattr(self, name) for name in V.StepOut._fields)),
        )

    @property
    def now(self) -> np.ndarray:
        """Each line's simulated time, s (a view)."""
        return self.gf[:, L.NOW]

    @property
    def deciding(self) -> np.ndarray:
        """(n, robots) bool: the robots of each line's pending epoch."""
        return self.ist[:, :, L.PENDING] != 0
