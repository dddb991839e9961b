"""Score a multi-agent policy on a task's evaluation seeds, on the multi-agent vector env.

:func:`rates` runs one line per evaluation seed in a
:class:`~pnp_twin.learning.envs.vector_marl.PickPlaceParallelVectorEnv` of the task (line e
on seed ``seeds[e]``, the run's whole length) and returns each line's gripping rate G at its
episode's end: the command line's measure (parts fed after the warm-up; for a fixed rule the
same value as ``pnp-twin task score``, tested). A policy is a function ``(obs, mask) ->
actions`` of the env's arrays ((lines, agents, ...) -> (lines, agents) rule indices):
a trained :class:`~pnp_twin.learning.marl_ppo.AgentPolicy`'s ``act``, :func:`fixed_rule`
or :func:`random_rules`. :func:`compare` gives the mean with its 95 % t-interval and the
paired per-seed differences to the reference policies.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from pnp_twin.learning.tasks import Task, get_task, make_env
from pnp_twin.twin.stats import t_interval

Act = Callable[[np.ndarray, np.ndarray], np.ndarray]
RULES = ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT")
"""The action set of the baselines: all six rules (the envs' default is the paper's five)."""


def fixed_rule(name: str, rules: Sequence[str] = RULES) -> Act:
    """Every robot takes rule ``name`` at every decision."""
    index = list(rules).index(name)

    def act(obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        return np.full(mask.shape[:2], index, dtype=np.int64)

    return act


def random_rules(seed: int = 0) -> Act:
    """Random rules: every robot draws one of the env's rules uniformly at every decision."""
    rng = np.random.default_rng(seed)

    def act(obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        return rng.integers(0, mask.shape[2], size=mask.shape[:2])

    return act


def rates(
    task: str | Task,
    act: Act,
    seeds: Sequence[int],
    *,
    skip_noops: bool = True,
    duration: float | None = None,
    rules: Sequence[str] = RULES,
) -> list[float]:
    """G (%) per seed of ``act`` on ``task``'s line (actions index ``rules``), one line per
    seed, run to its end."""
    t = get_task(task)
    extra: dict[str, Any] = {} if duration is None else {"overrides": t.settings(duration)}
    n = len(seeds)
    env = make_env(
        t, "parallel_vector", num_envs=n, skip_noops=skip_noops, rules=tuple(rules), **extra
    )
    env.reset(seed=0, options={"line_seed": int(seeds[0])})
    obs = info = None
    for e in range(n):
        mask = np.zeros(n, dtype=bool)
        mask[e] = True
        obs, info = env.reset(options={"line_seed": int(seeds[e]), "reset_mask": mask})
    assert obs is not None and info is not None
    out = np.full(n, np.nan)
    while np.isnan(out).any():
        obs, _r, term, trunc, info = env.step(act(obs, info["action_mask"]))
        ended = (term | trunc) & np.isnan(out)
        out[ended] = info["gripping_rate"][ended]
    env.close()
    return [float(g) for g in out]


def summary(
    values: Sequence[float],
    references: Mapping[str, Sequence[float]] | None = None,
    confidence: float = 0.95,
) -> dict[str, Any]:
    """Mean G with its t-interval, and per reference the paired difference's t-interval."""
    g, low, high = t_interval(list(values), confidence)
    out: dict[str, Any] = {"gripping_rate": g, "ci_low": low, "ci_high": high,
                           "per_seed": list(values)}  # fmt: skip
    for name, ref in (references or {}).items():
        diff = np.asarray(values) - np.asarray(ref)
        d, d_low, d_high = t_interval(list(diff), confidence)
        out[f"vs_{name}"] = {"diff": d, "ci_low": d_low, "ci_high": d_high}
    return out


__all__ = ["RULES", "Act", "fixed_rule", "random_rules", "rates", "summary"]
