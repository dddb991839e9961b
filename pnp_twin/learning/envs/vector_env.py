"""``PickPlaceVectorEnv``: many ``PickPlace-v0`` lines stepped in one compiled call."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from pnp_twin.learning.envs.common import EpisodeLimits, ObservationView, line_seed
from pnp_twin.learning.envs.driver import EnvError, check_rules, resolve_scenario
from pnp_twin.learning.envs.gym_env import ACTION_TYPES
from pnp_twin.learning.envs.options import env_options
from pnp_twin.twin.camera import CHANNELS
from pnp_twin.twin.fast import layout as L
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

FAST_RULES = L.RULE_NAMES[:-1]
"""The rules the compiled engine runs (FIFO LIFO SIRO SD LD SPT)."""


class PickPlaceVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` copies of :class:`~pnp_twin.learning.envs.gym_env.PickPlaceEnv` on the
    compiled engine (:mod:`twin.fast`), stepped together in one call on numba's threads.

    Step for step it gives what ``gymnasium.vector.SyncVectorEnv`` of ``PickPlaceEnv`` with
    the same arguments gives (same seeds, same actions: identical observations, rewards,
    terminations, truncations and infos), only faster. Spaces, rewards, episode ends and
    seeds are those of ``PickPlaceEnv`` (see its docstring); here batched:

    - ``single_observation_space`` / ``single_action_space``: ``PickPlaceEnv``'s;
      ``observation_space`` / ``action_space`` their batches over ``num_envs``
      (a ``(num_envs, C, H, W)`` uint8 box; ``MultiDiscrete`` actions, one row per env).
    - Autoreset: ``metadata["autoreset_mode"]`` is ``AutoresetMode.NEXT_STEP`` (Gymnasium's
      default): the step after an env's episode ended resets it, ignores its action and
      returns its first observation with reward 0, not terminated, not truncated.
    - ``reset(seed=s)``: env i is seeded with ``s + i`` (a list gives one seed per env,
      None draws fresh entropy); each env's own generator draws its line seeds as
      ``PickPlaceEnv.reset`` does. ``options={"line_seed": k}`` runs line seed ``k`` in
      every env; ``options={"reset_mask": mask}`` resets only the envs in ``mask``.
    - ``info``: ``PickPlaceEnv``'s keys as arrays over envs, each with Gymnasium's ``_key``
      mask: ``time``, ``tau``, ``line_seed``, ``gripping_rate``, ``skipped`` (num_envs,);
      ``deciding`` (bool), ``picks``, ``noops``, ``option_time`` and ``candidates``
      (num_envs, robots); ``action_mask`` (num_envs, K**N) for ``"discrete"`` actions,
      (num_envs, N, K) for ``"multidiscrete"``, int8 as ``PickPlaceEnv``'s.
    - ``skip_noops=True`` skips the epochs where no deciding robot has a choice, exactly as
      ``PickPlaceEnv`` does (in the compiled step).

    Arguments as ``PickPlaceEnv`` (``scenario``, ``action_type`` and the options of
    :class:`~pnp_twin.learning.envs.options.EnvOptions`; ``rules`` among FIFO LIFO SIRO SD
    LD SPT), plus ``num_envs``, ``copy`` (return copies of the observation buffer, as
    ``SyncVectorEnv(copy=True)``; False returns the buffer the next step overwrites) and
    ``threads`` (numba threads per step; None: one, which on a busy machine is faster than
    two, see :mod:`pnp_twin.learning.vector.batch`; give 2 on cores of your own). No rendering.

    The first use compiles the step (about a minute of CPU; once per change of the code,
    then read from numba's on-disk cache); when it does, a one-line
    :class:`~pnp_twin.learning.vector.batch.CompileNotice` warning says so (a cache hit
    warns nothing).
    ``gymnasium.make_vec("pnp_twin/PickPlace-v0", num_envs=N,
    vectorization_mode="vector_entry_point")`` builds it with the spec's 5000-step cap
    (applied as ``PickPlaceEnv(max_episode_steps=5000)`` applies it: an episode that
    terminates on the cap's step is not also truncated, as Gymnasium's TimeLimit marks it).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        scenario: str | Path | Scenario = "paper_baseline",
        *,
        action_type: str = "discrete",
        copy: bool = True,
        threads: int | None = None,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        from pnp_twin.learning.vector import step as V
        from pnp_twin.learning.vector.batch import LineBatch

        opts = env_options(None, {"scenario": scenario, **options})
        self.options = opts
        n = _check_args(num_envs, action_type, opts.channels, render_mode)
        limits = EpisodeLimits.check(opts.step_cap, opts.max_episode_time)
        self.scenario = resolve_scenario(opts.scenario, opts.overrides, opts.termination)
        self.rules = _fast_rules(opts.rules)
        self.num_envs = n
        self.copy = copy
        self.render_mode = None
        self.action_type = action_type
        self.n_robots = r = self.scenario.robots.count
        self.reward_weights = opts.reward_weights
        self.noop_penalty = opts.noop_penalty
        params = {
            V.DURATION: self.scenario.duration,
            V.MAX_TIME: np.inf if limits.time is None else limits.time,
            V.W_EXT: self.reward_weights[0],
            V.W_INT: self.reward_weights[1],
            V.PENALTY: self.noop_penalty,
        }
        try:
            self.batch = LineBatch(
                self.scenario, n, opts.channels, params, limits.steps or 0,
                "SIRO" in self.rules, opts.skip_noops, threads,
            )  # fmt: skip
        except ValueError as e:
            raise EnvError(str(e)) from None
        self.view = ObservationView(opts.observation, self.batch.shape)
        k = len(self.rules)
        self.single_observation_space = self.view.space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.single_action_space: spaces.Space[Any]
        if action_type == "discrete":
            self.single_action_space = spaces.Discrete(k**r)
        else:
            self.single_action_space = spaces.MultiDiscrete([k] * r)
        self.action_space = batch_space(self.single_action_space, n)
        self._codes = np.array([L.RULE_NAMES.index(x) for x in self.rules], dtype=np.int64)
        self._powers = np.array([k ** (r - 1 - i) for i in range(r)], dtype=np.int64)
        # joint actions decoded once (625 on paper_baseline), as PickPlaceEnv does
        self._table: np.ndarray | None = None
        if action_type == "discrete" and k**r <= 1 << 16:
            self._table = (np.arange(k**r)[:, None] // self._powers) % k
        self._masks: np.ndarray | None = None  # action_masks(): one joint mask per pattern
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._seeds = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=np.bool_)
        self.last_reset = self._autoreset
        """The envs the last :meth:`step` reset (Gymnasium's NEXT_STEP autoreset)."""
        self._started = False

    # -- the API ----------------------------------------------------------------------------
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        n = self.num_envs
        seeds = _env_seeds(seed, n)
        if isinstance(seed, int):
            super().reset(seed=seed)
        opts = dict(options or {})
        mask = _reset_mask(opts.pop("reset_mask", None), n, self._started)
        for e in np.flatnonzero(mask).tolist():
            if seeds[e] is not None or self._rngs[e] is None:
                self._rngs[e] = seeding.np_random(seeds[e])[0]
            self._load(e, line_seed(self._rng(e), opts))
        self._run(np.zeros((n, self.n_robots), dtype=np.int64), mask)
        self._autoreset[mask] = False
        self._started = True
        return self._obs(), self._info(mask)

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if not self._started:
            raise EnvError("step: the environments are not started; call reset()")
        codes = self._decode(actions)
        fresh = self._autoreset
        self.last_reset = fresh
        for e in np.flatnonzero(fresh).tolist():
            self._load(e, line_seed(self._rng(e), None))
        self._run(codes, fresh, act=True)
        b = self.batch
        self._autoreset = b.term | b.trunc
        all_envs = np.ones(self.num_envs, dtype=np.bool_)
        return self._obs(), b.reward.copy(), b.term.copy(), b.trunc.copy(), self._info(all_envs)

    # -- actions ----------------------------------------------------------------------------
    def decode(self, actions: Any) -> np.ndarray:
        """The rule index per env and robot, (num_envs, robots), of a batch of actions."""
        a = np.asarray(actions)
        n, r, k = self.num_envs, self.n_robots, len(self.rules)
        if self.action_type == "discrete":
            top = k**r
            if a.shape != (n,) or a.dtype.kind not in "iu" or a.min() < 0 or a.max() >= top:
                raise EnvError(
                    f"actions: give {n} integers in 0..{top - 1} (one per env), got "
                    f"shape {a.shape} dtype {a.dtype}"
                )
            if self._table is not None:
                return self._table[a]
            return (a.astype(np.int64)[:, None] // self._powers) % k
        if a.shape != (n, r) or a.dtype.kind not in "iu" or a.min() < 0 or a.max() >= k:
            raise EnvError(
                f"actions: give ({n}, {r}) integers in 0..{k - 1} (a rule index per env and "
                f"robot), got shape {a.shape} dtype {a.dtype}"
            )
        return a.astype(np.int64)

    def _decode(self, actions: Any) -> np.ndarray:
        """The kernel's rule codes per env and robot."""
        return self._codes[self.decode(actions)]

    def action_masks(self) -> np.ndarray:
        """Every env's action mask now, as ``PickPlaceEnv``'s: (num_envs, K**N) int8 for
        ``"discrete"`` actions, (num_envs, N, K) for ``"multidiscrete"``."""
        n, k, r = self.num_envs, len(self.rules), self.n_robots
        choice = self.batch.cand > 0
        if self.action_type == "discrete" and self._table is not None and 2**r * k**r <= 1 << 22:
            if self._masks is None:  # the joint mask of each pattern of robots with a choice
                patterns = (np.arange(2**r)[:, None] >> np.arange(r)) & 1  # (2**r, r)
                free = (self._table[None, :, :] == 0) | (patterns[:, None, :] == 1)
                self._masks = free.all(axis=2).astype(np.int8)  # (2**r, K**N)
            return self._masks[choice @ (1 << np.arange(r))]
        rows = np.zeros((n, r, k), dtype=np.int8)
        rows[:, :, 0] = 1
        rows[choice] = 1
        if self.action_type != "discrete":
            return rows
        out = np.ones((n, 1), dtype=np.int8)
        for r in range(self.n_robots):
            out = (out[:, :, None] * rows[:, r, None, :]).reshape(n, -1)
        return out

    # -- helpers ----------------------------------------------------------------------------
    def _rng(self, e: int) -> np.random.Generator:
        rng = self._rngs[e]
        assert rng is not None
        return rng

    def _load(self, e: int, seed: int) -> None:
        self._seeds[e] = seed
        self.batch.load(e, seed)

    def _run(self, codes: np.ndarray, fresh: np.ndarray, act: bool = False) -> None:
        from pnp_twin.learning.vector.step import ACT, RESET, SKIP

        mode = np.where(fresh, RESET, ACT if act else SKIP).astype(np.int8)
        self.batch.step(codes, mode)

    def _obs(self) -> np.ndarray:
        obs = self.batch.obs
        if self.view.image:
            s = self.view.scale
            return obs.repeat(s, axis=2).repeat(s, axis=3) * np.uint8(255)
        return obs.copy() if self.copy else obs

    def _info(self, mask: np.ndarray) -> dict[str, Any]:
        b = self.batch
        info: dict[str, Any] = {
            "tau": b.tau.copy(),
            "time": b.now.copy(),
            "picks": b.picks.copy(),
            "noops": b.noops.copy(),
            "deciding": b.deciding,
            "option_time": b.options.copy(),
            "candidates": b.cand.copy(),
            "action_mask": self.action_masks(),
            "skipped": b.skipped.copy(),
            "gripping_rate": b.grip.copy(),
            "line_seed": self._seeds.copy(),
        }
        for key in list(info):
            info[f"_{key}"] = mask
        return info


def _check_args(
    num_envs: int,
    action_type: str,
    channels: int,
    render_mode: str | None,
) -> int:
    """The constructor's argument checks that need no scenario; returns num_envs."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
        raise EnvError(f"num_envs: {num_envs!r} is not allowed; give an integer >= 1")
    if action_type not in ACTION_TYPES:
        raise EnvError(
            f"action_type: {action_type!r} is not allowed; use one of {', '.join(ACTION_TYPES)}"
        )
    if isinstance(channels, bool) or channels not in range(1, len(CHANNELS) + 1):
        raise EnvError(
            f"channels: {channels!r} is not allowed; give 1 to {len(CHANNELS)} "
            f"({', '.join(CHANNELS)})"
        )
    if render_mode is not None:
        raise EnvError(f"render_mode: {render_mode!r} is not allowed; the vector env has none")
    return int(num_envs)


def _fast_rules(rules: Sequence[str]) -> tuple[str, ...]:
    names = check_rules(rules)
    for name in names:
        if name not in FAST_RULES:
            raise EnvError(
                f"rules: {name!r} is not a rule of the compiled engine; allowed "
                f"{', '.join(FAST_RULES)}"
            )
    return names


def _env_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    """Gymnasium's vector seeding: None for all, ``seed + i``, or one seed per env."""
    if seed is None:
        return [None] * n
    if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)  # type: ignore[arg-type]
    if len(seeds) != n:
        raise EnvError(f"seed: {len(seeds)} seeds given for {n} envs; give one per env")
    return seeds


def _reset_mask(mask: Any, n: int, started: bool) -> np.ndarray:
    if mask is None:
        return np.ones(n, dtype=np.bool_)
    m = np.asarray(mask)
    if m.shape != (n,) or m.dtype != np.bool_ or not m.any():
        raise EnvError(
            f"options: reset_mask must be a bool array of shape ({n},) with at least one True"
        )
    if not started and not m.all():
        raise EnvError("options: reset_mask: the first reset must reset every env")
    return m
