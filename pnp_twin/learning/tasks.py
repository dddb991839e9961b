"""The task suite: named lines with fixed seeds and one metric, to score any policy on.

Each :class:`Task` is a line (a shipped scenario plus overrides), a termination scheme, the
run's length and warm-up, fixed **training seeds** (the range the HDQN trainer draws its
episodes' line seeds from) and disjoint **evaluation seeds** (1000-1019), and its metric:
the gripping rate G over the command line's window (parts fed after the warm-up), the
``gripping_rate`` KPI ``pnp-twin run`` reports. The tasks span lines where coordination
matters little (the baseline) to lines where a smarter controller gains more (a slow robot,
breakdowns, bursty arrivals, long workspaces).

:func:`score` runs a policy (any spec :func:`pnp_twin.policies.make_policy` takes: a rule, a
mix, ``hdqn:DIR``, ``sb3:MODEL.zip``, ``lookahead:...``) and the six rules on the same
evaluation seeds (common random numbers: the same part stream for every policy): the
policy's mean G with its 95 % t-interval, and its paired difference to the task's best rule
(the best of the six on these seeds) with the t-interval of the per-seed differences, as
``pnp-twin evaluate`` and ``headroom`` compute them. ``pnp-twin task score TASK --policy P``
prints it.

:func:`make_env` builds a Gymnasium, PettingZoo or vector env of a task's line:

>>> env = make_env("slow_robot", "gym")                         # doctest: +SKIP
>>> obs, info = env.reset(options={"line_seed": TASKS["slow_robot"].eval_seeds[0]})  # +SKIP
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from importlib import resources
from typing import Any

import numpy as np

from pnp_twin.learning.evaluate import gripping_rates
from pnp_twin.policies.registry import make_policy
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.errors import UserError, clip
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.stats import t_interval

TRAIN_SEEDS = range(1_000_000, 2**31)
"""Training line seeds: the range the HDQN trainer draws from (``TRAIN_SEED_BASE``)."""
EVAL_SEEDS = range(1000, 1020)
"""Evaluation line seeds: disjoint from training, validation (500,000 + i), tuning
(600,000 + i) and the seeds 0-19 and 100-105 the README's figures were measured or tuned on."""
KINDS = ("gym", "aec", "parallel", "vector", "parallel_vector")
"""The env kinds :func:`make_env` builds."""


class TaskError(UserError):
    """An unknown task, bad seeds or a bad env kind; the message is one line."""


@dataclass(frozen=True)
class Task:
    """One task of the suite (see the module docstring)."""

    name: str
    description: str
    """One line: what the line is and why coordination matters there."""
    scenario: str = "paper_baseline"
    """A shipped scenario name."""
    overrides: tuple[tuple[str, Any], ...] = ()
    """Dotted-path overrides, as ``--set`` takes them."""
    termination: str = "t_continue"
    duration: float = 600.0
    """Feeding time per run, s."""
    warmup: float = 60.0
    """Parts fed before this are not counted, s."""
    train_seeds: range = TRAIN_SEEDS
    eval_seeds: range = EVAL_SEEDS
    metric: str = field(default="gripping_rate")
    """The KPI scored: G over the command line's window (parts fed after the warm-up)."""
    version: int = 1
    """A released version never changes (its file neither); a changed task is a new one."""

    @property
    def id(self) -> str:
        """The versioned name, ``slow_robot-v1``: what results should cite."""
        return f"{self.name}-v{self.version}"

    def settings(self, duration: float | None = None) -> dict[str, Any]:
        """Every override of the task's line (``duration``: a shorter run, for tests)."""
        length = self.duration if duration is None else float(duration)
        warmup = self.warmup if duration is None else min(self.warmup, length / 5.0)
        return {
            **dict(self.overrides),
            "termination": self.termination,
            "duration": length,
            "warmup": warmup,
        }

    def line(self, duration: float | None = None) -> Scenario:
        """The task's scenario, overrides, termination, duration and warm-up applied."""
        return load_scenario(self.scenario, self.settings(duration))

    def command(self) -> str:
        """The ``pnp-twin run`` arguments that run this line."""
        sets = "".join(f" --set '{k}={_yaml(v)}'" for k, v in self.overrides)
        return f"{self.scenario}{sets}"

    def line_text(self) -> str:
        """The scenario and its overrides, short: ``paper_baseline feeder.rate=15``."""
        return " ".join([self.scenario, *(f"{k}={_yaml(v)}" for k, v in self.overrides)])

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "version": self.version,
            "id": self.id,
            "description": self.description,
            "scenario": self.scenario,
            "overrides": dict(self.overrides),
            "termination": self.termination,
            "duration": self.duration,
            "warmup": self.warmup,
            "train_seeds": [self.train_seeds.start, self.train_seeds.stop - 1],
            "eval_seeds": [self.eval_seeds.start, self.eval_seeds.stop - 1],
            "metric": self.metric,
        }


def _yaml(value: Any) -> str:
    """An override value as ``--set`` reads it (flow YAML)."""
    if isinstance(value, list):
        return "[" + ", ".join(_yaml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_yaml(v)}" for k, v in value.items()) + "}"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _read_task(text: str, where: str) -> Task:
    """A task from its TOML file (the keys :meth:`Task.to_json` writes, plus ``version``)."""
    data = tomllib.loads(text)
    known = {"name", "version", "description", "scenario", "termination", "duration",
             "warmup", "train_seeds", "eval_seeds", "metric", "overrides"}  # fmt: skip
    extra = sorted(set(data) - known)
    if extra:
        raise TaskError(f"task file {where}: unknown key '{extra[0]}'")
    first, last = data.pop("train_seeds"), data.pop("eval_seeds")
    return Task(
        **{k: v for k, v in data.items() if k != "overrides"},
        overrides=tuple(data.get("overrides", {}).items()),
        train_seeds=range(int(first[0]), int(first[1]) + 1),
        eval_seeds=range(int(last[0]), int(last[1]) + 1),
    )


def _load_suite() -> tuple[Task, ...]:
    """Every task file of :mod:`pnp_twin.learning.suite`, in :data:`ORDER`, then by version."""
    root = resources.files("pnp_twin.learning.suite")
    tasks = [
        _read_task(f.read_text(encoding="utf-8"), f.name)
        for f in root.iterdir()
        if f.name.endswith(".toml")
    ]
    for t in tasks:
        if t.name not in ORDER:
            raise TaskError(f"task file {t.id}: '{t.name}' is not in the suite's ORDER")
    return tuple(sorted(tasks, key=lambda t: (ORDER.index(t.name), t.version)))


ORDER = ("baseline", "high_load", "slow_robot", "breakdowns", "bursty", "long_workspaces")
"""The suite's tasks, in the order ``pnp-twin task list`` prints them."""
VERSIONS: tuple[Task, ...] = _load_suite()
"""Every version of every task (``pnp_twin/learning/suite/NAME-vN.toml``)."""
LATEST: dict[str, Task] = {t.name: t for t in VERSIONS}
SUITE: tuple[Task, ...] = tuple(LATEST[n] for n in ORDER)
"""The suite: each task's newest version, in :data:`ORDER`."""

TASKS: dict[str, Task] = {t.name: t for t in SUITE}
"""Tasks by name (the newest version)."""
BY_ID: dict[str, Task] = {t.id: t for t in VERSIONS}
"""Every version by its id (``slow_robot-v1``)."""


def get_task(name: str | Task) -> Task:
    """The task named ``name`` (its newest version) or with id ``name`` (``slow_robot-v1``);
    a :class:`Task` is returned as it is."""
    if isinstance(name, Task):
        return name
    key = str(name).strip().lower()
    task = TASKS.get(key) or BY_ID.get(key)
    if task is None:
        names = ", ".join(t.name for t in SUITE)
        raise TaskError(
            f"task: unknown '{clip(str(name))}'; the tasks are {names} (or NAME-vN, a version)"
        )
    return task


def eval_seeds(task: Task, seeds: int | None = None) -> list[int]:
    """The first ``seeds`` evaluation seeds of ``task`` (None: all); 2 at least."""
    pool = task.eval_seeds
    n = len(pool) if seeds is None else seeds
    if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= len(pool):
        raise TaskError(
            f"--seeds: {clip(repr(seeds))} is not allowed; give 2 to {len(pool)} (the task's "
            f"evaluation seeds {pool.start}-{pool.stop - 1})"
        )
    return list(pool[:n])


@dataclass(frozen=True)
class Score:
    """A policy's score on a task (:func:`score`)."""

    task: Task
    policy: str
    seeds: list[int]
    values: list[float]
    """The policy's G per seed."""
    rules: dict[str, list[float]]
    """Each rule's G per seed."""
    best_rule: str
    duration: float
    warmup: float
    engine: str
    confidence: float = 0.95

    @property
    def interval(self) -> tuple[float, float, float]:
        """(mean G, low, high): the policy's t-interval."""
        return t_interval(self.values, self.confidence)

    @property
    def difference(self) -> tuple[float, float, float]:
        """(mean, low, high) of the per-seed G(policy) - G(best rule), paired."""
        diff = np.asarray(self.values) - np.asarray(self.rules[self.best_rule])
        return t_interval(list(diff), self.confidence)

    def to_json(self) -> dict[str, Any]:
        g, low, high = self.interval
        d, d_low, d_high = self.difference
        b, b_low, b_high = t_interval(self.rules[self.best_rule], self.confidence)
        return {
            "task": self.task.name,
            "policy": self.policy,
            "metric": self.task.metric,
            "seeds": self.seeds,
            "duration": self.duration,
            "warmup": self.warmup,
            "engine": self.engine,
            "confidence": self.confidence,
            "gripping_rate": g,
            "ci_low": low,
            "ci_high": high,
            "best_rule": {
                "policy": self.best_rule,
                "gripping_rate": b,
                "ci_low": b_low,
                "ci_high": b_high,
            },
            "diff": d,
            "diff_ci_low": d_low,
            "diff_ci_high": d_high,
            "per_seed": self.values,
            "rules": {r: float(np.mean(v)) for r, v in self.rules.items()},
        }


def _rate(job: tuple[Scenario, str, int, str]) -> float:
    """G of one run of a fresh policy (module level: picklable for worker processes)."""
    line, spec, seed, engine = job
    return gripping_rates(line, partial(make_policy, spec, line.robots.count), [seed], engine)[0]


def _rates(
    line: Scenario, spec: str, seeds: Sequence[int], engine: str, workers: int
) -> list[float]:
    jobs = [(line, spec, s, engine) for s in seeds]
    if workers > 1 and len(jobs) > 1:
        from pnp_twin.parallel import pool_map_ordered

        return [float(g) for g in pool_map_ordered(_rate, jobs, workers)]
    return [_rate(job) for job in jobs]


def score(
    task: str | Task,
    policy: str,
    seeds: int | None = None,
    *,
    engine: str = "fast",
    workers: int = 1,
    duration: float | None = None,
    confidence: float = 0.95,
    progress: Callable[[str], None] | None = None,
) -> Score:
    """Score ``policy`` on ``task``'s first ``seeds`` evaluation seeds against the six rules.

    ``engine``: simpy, fast or auto (same results); ``workers``: processes; ``duration``:
    a shorter run than the task's (for tests; the warm-up shrinks to a fifth of it at most),
    not the task's score.
    """
    t = get_task(task)
    seed_list = eval_seeds(t, seeds)
    line = t.line(duration)
    spec = policy.strip()
    make_policy(spec, line.robots.count)  # a bad spec fails before any run
    rules: dict[str, list[float]] = {}
    for rule in RULES:
        rules[rule] = _rates(line, rule, seed_list, engine, workers)
        if progress is not None:
            progress(rule)
    best = max(RULES, key=lambda r: (float(np.mean(rules[r])), -list(RULES).index(r)))
    upper = spec.upper()
    if upper in RULES:
        values = list(rules[upper])
    else:
        values = _rates(line, spec, seed_list, engine, workers)
        if progress is not None:
            progress(spec)
    return Score(t, spec, seed_list, values, rules, best, line.duration, line.warmup, engine,
                 confidence)  # fmt: skip


def make_env(task: str | Task, kind: str = "gym", **options: Any) -> Any:
    """An env of ``task``'s line: ``gym`` (:class:`PickPlaceEnv`), ``aec`` (PettingZoo AEC,
    order-enforcing wrapper), ``parallel`` (PettingZoo Parallel), ``vector``
    (:class:`PickPlaceVectorEnv`) or ``parallel_vector`` (:class:`PickPlaceParallelVectorEnv`).

    The env gets the task's scenario and overrides (duration and warm-up included) and
    termination; ``options`` are the env's keyword arguments (``num_envs`` for the vector
    kinds, ``render_mode``, any :class:`EnvOptions` field) and override the task's.
    Reset with ``options={"line_seed": k}`` for ``k`` in ``task.train_seeds`` to train and
    ``task.eval_seeds`` to evaluate.
    """
    t = get_task(task)
    if kind not in KINDS:
        raise TaskError(
            f"kind: '{clip(str(kind))}' is not an env kind; give one of {', '.join(KINDS)}"
        )
    extra: Mapping[str, Any] = options.pop("overrides", None) or {}
    kwargs: dict[str, Any] = {
        "scenario": t.scenario,
        "overrides": {**t.settings(), **extra},
        "termination": t.termination,
        **options,
    }
    if kind == "gym":
        from pnp_twin.learning.envs.gym_env import PickPlaceEnv

        return PickPlaceEnv(**kwargs)
    if kind == "aec":
        from pnp_twin.learning.envs import pickplace_v0

        return pickplace_v0.env(**kwargs)
    if kind == "parallel":
        from pnp_twin.learning.envs.pz_parallel import PickPlaceParallel

        return PickPlaceParallel(**kwargs)
    if kind == "vector":
        from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv

        return PickPlaceVectorEnv(**kwargs)
    from pnp_twin.learning.envs.vector_marl import PickPlaceParallelVectorEnv

    return PickPlaceParallelVectorEnv(**kwargs)


__all__ = [
    "EVAL_SEEDS",
    "KINDS",
    "SUITE",
    "TASKS",
    "TRAIN_SEEDS",
    "Score",
    "Task",
    "TaskError",
    "eval_seeds",
    "get_task",
    "make_env",
    "score",
]
