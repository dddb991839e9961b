"""The epoch driver: the twin paused at each decision epoch, for reinforcement learning.

:class:`EpochDriver` runs a :class:`~twin.line.Line` in hold mode with a
:class:`~policies.base.SettableRules` policy. At each decision epoch the gateway pauses the
simulation and lists the robots that are free; the driver hands their rule choices to the
policy, releases them and advances to the next epoch. It also keeps the per-robot option
bookkeeping (an *option* lasts from a robot's decision to its next one) from which the
environments compute the paper's rewards, and draws the observations.

The Gymnasium and PettingZoo environments in this package are thin layers over it; the HDQN
trainer may use it directly.

**Copies.** SimPy processes are generators, which cannot be copied; a driver instead remembers
its seed and the actions since the last reset, and ``copy.deepcopy`` / ``pickle`` rebuild the
line and replay them (:meth:`EpochDriver.__setstate__`). The copy continues exactly as the
original would; its cost grows with the number of steps since the reset (``bench/bench_env.py``
measures it).
"""

from __future__ import annotations

import logging
import math
from bisect import bisect_left
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.learning.envs.defaults import NOOP_PENALTY, REWARD_WEIGHTS
from pnp_twin.policies.base import SettableRules
from pnp_twin.policies.registry import rule_names
from pnp_twin.policies.rules import PAPER_RULES
from pnp_twin.twin.camera import CHANNELS, BeltCamera
from pnp_twin.twin.decision import Decision
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.gateway import SCHEMES
from pnp_twin.twin.line import Line
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

NOOP = "NooP"


class EnvError(UserError):
    """A bad environment argument; the message is one line naming it and what is allowed."""


@dataclass(frozen=True, slots=True)
class OptionResult:
    """A robot's option that just ended: from its decision at ``start`` to its next one.

    ``picks`` is 1 if the robot gripped the part it chose (0 for a NooP, or a claim that a
    t_any epoch interrupted); ``duration`` in simulated seconds includes any waiting for a
    synchronous epoch and any breakdown before the robot was free again.
    """

    picks: int
    duration: float
    noop: bool
    start: float


def extrinsic_reward(option: OptionResult) -> float:
    """The paper's eq. 1: picks per second of the option, 0 when it picked nothing."""
    if option.picks and option.duration > 0.0:
        return option.picks / option.duration
    return 0.0


def intrinsic_reward(option: OptionResult, noop_penalty: float = NOOP_PENALTY) -> float:
    """The paper's eq. 2: ``-noop_penalty`` for a NooP, else 0."""
    return -noop_penalty if option.noop else 0.0


def resolve_scenario(
    scenario: str | Path | Scenario,
    overrides: Mapping[str, Any] | None = None,
    termination: str | None = None,
) -> Scenario:
    """A Scenario from a path, a shipped name or an object, with overrides applied."""
    if termination is not None and termination not in SCHEMES:
        raise EnvError(
            f"termination: {termination!r} is not a scheme; allowed {', '.join(SCHEMES)}"
        )
    extra = dict(overrides or {})
    if termination is not None:
        extra["termination"] = termination
    if isinstance(scenario, Scenario):
        return with_overrides(scenario, extra) if extra else scenario
    return load_scenario(scenario, extra or None)


def check_rules(rules: Sequence[str]) -> tuple[str, ...]:
    """Upper-cased rule names, each one known to the rule registry (one ``rules:`` line)."""
    try:
        return rule_names(rules)
    except ValueError as e:
        raise EnvError(f"rules: {e}") from None


def is_rule_index(action: object, k: int) -> bool:
    """True for an integer (or 0-d integer array) in 0..k-1; cheaper than Discrete.contains."""
    if isinstance(action, int | np.integer):
        return bool(0 <= action < k)
    if isinstance(action, np.ndarray) and action.shape == () and action.dtype.kind in "iu":
        return 0 <= int(action) < k
    return False


class _RecordingRules(SettableRules):
    """SettableRules that remembers the part each robot chose (its option's claim)."""

    def __init__(self, n_robots: int, claims: list[int]) -> None:
        super().__init__(n_robots)
        self.claims = claims

    def choose(self, decision: Decision) -> int:
        k = super().choose(decision)
        self.claims[decision.robot] = decision.parts[k]
        return k


class EpochDriver:
    """A line paused at every decision epoch; robots are 0-based indices, upstream first.

    Args:
        scenario: a Scenario, a path to a scenario file or a shipped scenario name.
        seed: the default seed of :meth:`reset` (the scenario's when None).
        termination: t_continue | t_all | t_any; the scenario's when None.
        rules: the rule names an action index refers to (default the paper's five:
            FIFO LIFO SIRO SD LD).
        channels: observation channels (1 to 3), see :class:`~twin.camera.BeltCamera`.
        overrides: dotted-path scenario overrides, e.g. ``{"feeder.rate": 12}``.
        reward_weights, noop_penalty: the default weights of eq. 1 and eq. 2 and the NooP
            penalty of :meth:`reward` and of :attr:`step_rewards`.

    The episode is the scenario's feeding time: :attr:`done` turns true at the first epoch
    at or after ``scenario.duration`` (no part is fed after it).

    Use: ``deciding = d.reset(seed)``; then repeatedly ``deciding = d.act({robot: k})`` with
    a rule index ``k`` for each robot in ``deciding``. After each call, for every robot in
    ``deciding``, ``d.option(robot)`` is the option that just ended (None at the first
    epoch) and ``d.reward(robot, weights, noop_penalty)`` its eq. 1 + eq. 2 reward.
    ``d.observe(None)`` is the whole belt, ``(C, H, W)`` = (C, 8, 64) on paper_baseline;
    ``d.observe(robot)`` the robot's workspace window, ``(C, H, w)``, a fixed width ``w``
    (the widest workspace in cells; (1, 8, 7) on paper_baseline) from the cell holding its
    workspace start. Channels: 0 parts, 1 claimed parts, 2 busy robots' workspace columns
    (see :mod:`twin.camera`).

    **Choices.** :attr:`candidates` counts, per robot of the epoch, the parts it could pick
    now (0 for robots not deciding). A deciding robot with none takes a NooP whatever its
    rule (claims by robots deciding before it in the same epoch can only take candidates
    away, never add one), so its action changes nothing: :meth:`has_choice` is False.
    ``act(..., skip_noops=True)`` answers such epochs itself and runs on to the next epoch
    where a robot has a choice; :attr:`step_rewards`, :attr:`step_picks` and
    :attr:`step_noops` then sum over every epoch the call passed.
    """

    def __init__(
        self,
        scenario: str | Path | Scenario = "paper_baseline",
        seed: int | None = None,
        termination: str | None = None,
        rules: Sequence[str] = PAPER_RULES,
        channels: int = 1,
        overrides: Mapping[str, Any] | None = None,
        reward_weights: tuple[float, float] = REWARD_WEIGHTS,
        noop_penalty: float = NOOP_PENALTY,
    ) -> None:
        self.scenario = resolve_scenario(scenario, overrides, termination)
        self.weights = (float(reward_weights[0]), float(reward_weights[1]))
        self.noop_penalty = float(noop_penalty)
        self.rules = check_rules(rules)
        self.seed = self.scenario.seed if seed is None else seed
        self.n_robots = self.scenario.robots.count
        if not 1 <= channels <= len(CHANNELS):
            raise EnvError(
                f"channels: {channels} is not allowed; give 1 to {len(CHANNELS)} "
                f"({', '.join(CHANNELS)})"
            )
        self.camera = BeltCamera(self.scenario, channels)
        self.channels = channels
        self.line: Line | None = None
        self.deciding: list[int] = []
        self.steps = 0
        n = self.n_robots
        self._claims = [-1] * n
        self._started = [math.nan] * n
        self._noops_before = [0] * n
        self._options: list[OptionResult | None] = [None] * n
        self._step_picks = [0] * n
        self._total_picks = [0] * n
        self._passed = 0
        self._passed_picked = 0
        self._first = 0  # the first part fed at or after the warm-up (the KPI window)
        self.candidates = [0] * n
        """Per robot: candidate parts at the current epoch (0 when not deciding)."""
        self.step_rewards = [0.0] * n
        """Per robot: eq. 1 + eq. 2 of its options that ended during the last :meth:`act`."""
        self.step_noops = [0] * n
        """Per robot: NooPs taken during the last :meth:`act` (forced ones included)."""
        self.skipped = 0
        """Epochs the last :meth:`act` answered itself (``skip_noops``)."""
        self._init = {
            "scenario": self.scenario,
            "seed": seed,
            "rules": self.rules,
            "channels": channels,
            "reward_weights": self.weights,
            "noop_penalty": self.noop_penalty,
        }
        self.history: list[dict[int, int]] = []
        """The actions since the last reset (what a copy replays)."""

    # -- copies ---------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """The constructor arguments, the seed and the actions since reset (no generators)."""
        started = self.line is not None
        return {
            "init": self._init,
            "seed": self.seed,
            "history": list(self.history),
            "started": started,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild the line and replay the recorded actions: the same state, step by step."""
        self.__init__(**state["init"])  # type: ignore[misc]
        self.seed = state["seed"]
        if state["started"]:
            self.replay(self.seed, state["history"])

    def replay(self, seed: int, history: Sequence[Mapping[int, int]]) -> list[int]:
        """Reset with ``seed`` and apply ``history`` (what :attr:`history` recorded): the
        driver is then exactly where the recorded one was. Returns the robots deciding."""
        self.reset(seed)
        for actions in history:
            self._act_once(actions)
        return self.deciding

    # -- running -------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> list[int]:
        """Start a fresh line (seed: the driver's default when None); the robots deciding."""
        if seed is not None:
            self.seed = int(seed)
        n = self.n_robots
        self._claims[:] = [-1] * n
        self._started[:] = [math.nan] * n
        self._noops_before[:] = [0] * n
        self._options[:] = [None] * n
        self._step_picks[:] = [0] * n
        self._total_picks[:] = [0] * n
        self._passed = self._passed_picked = 0
        self.step_rewards[:] = [0.0] * n
        self.step_noops[:] = [0] * n
        self.skipped = 0
        self.steps = 0
        self.history = []
        self.policy = _RecordingRules(n, self._claims)
        self.line = Line(self.scenario, self.policy, seed=self.seed, hold=True)
        self.camera.attach(self.line.belt)
        fed = self.line.belt.fed
        self._first = self._passed = bisect_left(fed, self.scenario.warmup)
        log.debug(
            "episode of %s, seed %d, %s", self.scenario.name, self.seed, self.scenario.termination
        )
        self._advance()
        return self.deciding

    def act(
        self,
        actions: Mapping[int, int],
        skip_noops: bool = False,
        auto: Sequence[int] = (),
        until: float = math.inf,
    ) -> list[int]:
        """Apply a rule index to each deciding robot, run to the next epoch; the robots then.

        Robots missing from ``actions`` keep their previous rule (FIFO at first); indices
        for robots that are not deciding are ignored. Epochs where no deciding robot waits
        for an agent are answered at once (every robot keeps its rule) until one does, the
        episode is over (:attr:`done`) or the time reaches ``until``: robots in ``auto``
        never wait (their agents are gone), and with ``skip_noops`` only robots with a
        choice (:meth:`has_choice`) do.
        """
        n = self.n_robots
        rewards, picks, noops = [0.0] * n, [0] * n, [0] * n
        self.skipped = 0
        while True:
            self._act_once(actions)
            for r in range(n):
                rewards[r] += self.step_rewards[r]
                picks[r] += self._step_picks[r]
                noops[r] += self.step_noops[r]
            if self.done or self.now >= until or self._needs_agent(skip_noops, auto):
                break
            actions = {}
            self.skipped += 1
        self.step_rewards[:] = rewards
        self._step_picks[:] = picks
        self.step_noops[:] = noops
        return self.deciding

    def skip_to_choice(
        self, skip_noops: bool = True, auto: Sequence[int] = (), until: float = math.inf
    ) -> list[int]:
        """At an epoch where no robot outside ``auto`` needs an agent (see :meth:`act`),
        run on as :meth:`act` does (after :meth:`reset`); else do nothing."""
        self.skipped = 0
        if self.done or self.now >= until or self._needs_agent(skip_noops, auto):
            return self.deciding
        act = self.act({}, skip_noops, auto, until)
        self.skipped += 1
        return act

    def _needs_agent(self, skip_noops: bool, auto: Sequence[int]) -> bool:
        """Whether a deciding robot outside ``auto`` waits for its agent's rule: any such
        robot, or with ``skip_noops`` one with a choice."""
        for r in self.deciding:
            if r not in auto and (not skip_noops or self.candidates[r] > 0):
                return True
        return False

    def has_choice(self, robot: int) -> bool:
        """True when ``robot`` decides now and has a candidate part (its rule matters)."""
        return self.candidates[robot] > 0

    def _act_once(self, actions: Mapping[int, int]) -> list[int]:
        line = self.line
        if line is None:
            raise RuntimeError("EpochDriver.act() called before reset()")
        rules, policy, now = self.rules, self.policy, line.env.now
        decisions = line.recorder.decisions
        for robot in self.deciding:
            k = actions.get(robot)
            if k is not None:
                if not 0 <= k < len(rules):
                    raise EnvError(
                        f"action: rule index {k} for robot {robot} is not in 0..{len(rules) - 1}"
                    )
                policy.rules[robot] = rules[k]
            self._claims[robot] = -1
            self._started[robot] = now
            self._noops_before[robot] = decisions[(robot, NOOP)]
            self._options[robot] = None
        self.history.append(dict(actions))
        line.gateway.release()
        self.steps += 1
        self._advance()
        return self.deciding

    def _advance(self) -> None:
        """Step the simulation to the next epoch and close the options that ended there."""
        line = self.line
        assert line is not None
        env, gateway = line.env, line.gateway
        pending = gateway.pending
        step, peek = env.step, env.peek
        while not pending:
            if peek() == math.inf:  # pragma: no cover - robots always come back in hold mode
                raise RuntimeError("the line ran out of events")
            step()
        now = env.now
        while peek() == now:  # robots free at the same instant share the epoch
            step()
        self.deciding = sorted(pending)
        self._collect(now)
        robots, candidates = line.robots, self.candidates
        for r in range(self.n_robots):
            candidates[r] = 0
        for r in self.deciding:
            candidates[r] = len(robots[r]._candidates(now)[0])

    def _collect(self, now: float) -> None:
        assert self.line is not None
        rec = self.line.recorder
        picked_at, picker = rec.picked_at, rec.robot
        step_picks, claims = self._step_picks, self._claims
        for r in range(self.n_robots):
            step_picks[r] = 0
            part = claims[r]
            if part >= 0 and picker[part] == r and picked_at[part] == picked_at[part]:
                step_picks[r] = 1
                self._total_picks[r] += 1
                claims[r] = -2  # this option picked its part
        decisions = rec.decisions
        rewards, noops = self.step_rewards, self.step_noops
        for r in range(self.n_robots):
            rewards[r] = 0.0
            noops[r] = 0
        w_e, w_i, penalty = self.weights[0], self.weights[1], self.noop_penalty
        for r in self.deciding:
            start = self._started[r]
            if start != start:  # the first epoch: no option ended
                continue
            option = OptionResult(
                picks=1 if claims[r] == -2 else 0,
                duration=now - start,
                noop=decisions[(r, NOOP)] > self._noops_before[r],
                start=start,
            )
            self._options[r] = option
            noops[r] = int(option.noop)
            rewards[r] = w_e * extrinsic_reward(option) + w_i * intrinsic_reward(option, penalty)

    # -- state --------------------------------------------------------------------------------
    @property
    def now(self) -> float:
        """Simulated time of the current epoch, s."""
        return 0.0 if self.line is None else float(self.line.env.now)

    @property
    def done(self) -> bool:
        """True once the feeding time is over (the episode terminates)."""
        return self.line is not None and self.line.env.now >= self.scenario.duration

    def option(self, robot: int) -> OptionResult | None:
        """The option that ended when ``robot`` became free for the current epoch, if any."""
        return self._options[robot]

    @property
    def step_picks(self) -> list[int]:
        """Picks (grips completed) per robot during the last :meth:`act`."""
        return list(self._step_picks)

    @property
    def total_picks(self) -> list[int]:
        """Picks per robot since :meth:`reset`."""
        return list(self._total_picks)

    def gripping_rate(self) -> float:
        """The gripping rate so far over the command line's window: percent picked of the
        parts fed at or after the warm-up that have passed the last workspace's end (0.0
        until one has)."""
        line = self.line
        if line is None:
            return 0.0
        belt = line.belt
        n = belt.passed(line.env.now)
        holder = belt.holder
        picked = self._passed_picked
        for i in range(self._passed, n):
            if holder[i] >= 0:
                picked += 1
        if n > self._passed:
            self._passed, self._passed_picked = n, picked
        seen = self._passed - self._first
        return 100.0 * picked / seen if seen > 0 else 0.0

    def observe(self, robot: int | None = None) -> np.ndarray:
        """The belt image (C, H, W) when ``robot`` is None, else the robot's window (C, H, w)."""
        line = self.line
        assert line is not None
        now, gateway = line.env.now, line.gateway
        if robot is None:
            return self.camera.belt(now, gateway.pending)
        return self.camera.window(robot, now, gateway.pending, gateway.epochs)

    def reward(
        self,
        robot: int,
        weights: tuple[float, float] | None = None,
        noop_penalty: float | None = None,
    ) -> float:
        """Weighted eq. 1 + eq. 2 of the option that just ended for ``robot`` (0 if none);
        the driver's weights and penalty unless given."""
        option = self._options[robot]
        if option is None:
            return 0.0
        w = self.weights if weights is None else weights
        penalty = self.noop_penalty if noop_penalty is None else noop_penalty
        return w[0] * extrinsic_reward(option) + w[1] * intrinsic_reward(option, penalty)
