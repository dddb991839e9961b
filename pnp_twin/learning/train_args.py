"""The settings of an HDQN training run: :class:`TrainArgs`, checked and completed.

Every field is a ``pnp-twin train`` option (the CLI builds its options from this class, the
field docs are their help). Fields left ``None`` scale with ``steps`` (:func:`settled`), so a
short run learns too: learning starts after 5 % of the steps (at most 5,000), epsilon decays
over 30 %, and a run logs 100 rows, evaluates 10 times and checkpoints 20 times.
"""

from __future__ import annotations

import ast
import inspect
import math
import re
from dataclasses import dataclass, field, fields, replace
from functools import cache
from typing import Any

from pnp_twin.learning.envs.driver import EnvError, check_rules
from pnp_twin.learning.envs.options import NOOP_PENALTY, REWARD_WEIGHTS
from pnp_twin.policies.hdqn import MODES
from pnp_twin.policies.rules import RULES

VIEWS = ("window", "belt")
"""Multi-agent observations: the robot's workspace window, or the whole belt."""
REWARDS = ("own", "downstream", "team")
"""Multi-agent rewards: eq. 1 + eq. 2 of the robot's option, or team picks during it."""


@dataclass
class TrainArgs:
    """Everything a training run depends on (recorded in its checkpoint)."""

    scenario: str = "paper_baseline"
    """Scenario file path or shipped name."""
    mode: str = "async"
    """single | sync | async."""
    out: str = "runs"
    """Output folder; the run writes into out/<scenario>__<mode>__<seed>/."""
    seed: int = 1
    """Seed of the run: exploration, minibatches, training episode seeds, torch init."""
    steps: int = 200_000
    """Meta-controller transitions to train for."""
    device: str = "auto"
    """auto (CUDA when available) | cpu | cuda | cuda:N."""
    network: str = "compact"
    """Q-network preset: compact | paper | pooled."""
    rules: tuple[str, ...] = tuple(RULES)
    """Rules an action index refers to (the options): the paper's five plus SPT."""
    channels: int = 1
    """Observation channels (1 = the paper's occupancy image; 2 adds claimed parts)."""
    view: str = "window"
    """Multi-agent observation: window (own workspace window) | belt (the whole belt)."""
    reward: str = "own"
    """Multi-agent reward: own (eq. 1 + eq. 2) | downstream | team (picks of the option)."""
    episode_time: float = 120.0
    """Simulated feeding time of a training episode, s (shorter than a scenario run)."""
    lr: float = 2.5e-4
    """RMSprop learning rate."""
    gamma: float = 0.9
    """Discount per simulated second (targets use gamma ** tau)."""
    double: bool = True
    """Double DQN targets."""
    buffer_size: int = 50_000
    """Replay capacity (transitions)."""
    batch_size: int = 64
    """Minibatch size."""
    learning_starts: int | None = None
    """Transitions before the first gradient step (default: 5 % of steps, at most 5,000)."""
    train_every: int = 4
    """Transitions between gradient steps."""
    target_every: int = 1_000
    """Gradient steps between target-network copies."""
    eps_start: float = 1.0
    """Initial exploration rate."""
    eps_end: float = 0.02
    """Final exploration rate."""
    eps_fraction: float = 0.3
    """Fraction of the steps over which epsilon decays linearly."""
    reward_weights: tuple[float, float] = REWARD_WEIGHTS
    """Weights of eq. 1 (picks per second) and eq. 2 (NooP penalty)."""
    noop_penalty: float = NOOP_PENALTY
    """Eq. 2's penalty per NooP."""
    eval_every: int | None = None
    """Steps between evaluations (default: steps / 10)."""
    eval_seeds: int = 4
    """Validation seeds per evaluation."""
    eval_duration: float = 300.0
    """Feeding time of an evaluation run, s (warm-up as in the scenario, capped at 1/5)."""
    log_every: int | None = None
    """Steps between rows of log.csv (default: steps / 100, at most 1,000)."""
    checkpoint_every: int | None = None
    """Steps between checkpoints of the exact resume state (default: steps / 20)."""
    save_replay: bool = True
    """Checkpoint the replay buffer too (needed for an exact resume)."""
    resume: bool = False
    """Continue the run from its last checkpoint."""
    threads: int = 1
    """torch CPU threads (the machine is shared)."""
    engine: str = "auto"
    """Engine of the validation runs (the rule baselines and the greedy HDQN) and of rollout
    labelling: simpy, fast or auto (same results)."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Dotted-path scenario overrides."""


def settled(args: TrainArgs) -> TrainArgs:
    """``args`` with every ``None`` default replaced by its value for ``args.steps``."""
    steps = max(1, int(args.steps))
    return replace(
        args,
        learning_starts=(
            min(5_000, steps // 20) if args.learning_starts is None else args.learning_starts
        ),
        eval_every=max(1, steps // 10) if args.eval_every is None else args.eval_every,
        log_every=max(1, min(1_000, steps // 100)) if args.log_every is None else args.log_every,
        checkpoint_every=(
            max(1, steps // 20) if args.checkpoint_every is None else args.checkpoint_every
        ),
    )


_POSITIVE = (
    "steps",
    "channels",
    "buffer_size",
    "batch_size",
    "train_every",
    "target_every",
    "eval_every",
    "eval_seeds",
    "log_every",
    "checkpoint_every",
    "threads",
)


def check_args(args: TrainArgs) -> tuple[str, ...]:
    """Raise one ``EnvError`` line for a bad setting; the checked rule names."""
    if args.mode not in MODES:
        raise EnvError(f"mode: '{args.mode}' is not a mode; allowed {', '.join(MODES)}")
    rules = check_rules(args.rules)
    if args.engine not in ("simpy", "fast", "auto"):
        raise EnvError(f"engine: '{args.engine}' is not an engine; allowed simpy, fast, auto")
    if args.view not in VIEWS:
        raise EnvError(f"view: '{args.view}' is not a view; allowed {', '.join(VIEWS)}")
    if args.reward not in REWARDS:
        raise EnvError(f"reward: '{args.reward}' is not a reward; allowed {', '.join(REWARDS)}")
    if args.mode == "single" and (args.view, args.reward) != ("window", "own"):
        raise EnvError("view/reward: single mode sees the whole belt with eq. 1 + eq. 2 only")
    for name in _POSITIVE:
        value = getattr(args, name)
        if value is not None and (not isinstance(value, int) or value < 1):
            raise EnvError(f"{name}: {value!r} is not allowed; give an integer >= 1")
    if args.learning_starts is not None and args.learning_starts < 0:
        raise EnvError(f"learning_starts: {args.learning_starts} is not allowed; give >= 0")
    for name, lo, hi in (
        ("gamma", 0.0, 1.0),
        ("eps_start", 0.0, 1.0),
        ("eps_end", 0.0, 1.0),
        ("eps_fraction", 0.0, 1.0),
    ):
        value = getattr(args, name)
        if not (math.isfinite(value) and lo <= value <= hi):
            raise EnvError(f"{name}: {value!r} is not allowed; give a number in [{lo}, {hi}]")
    for name in ("lr", "episode_time", "eval_duration"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            raise EnvError(f"{name}: {value!r} is not allowed; give a number > 0")
    if len(args.reward_weights) != 2 or not all(math.isfinite(w) for w in args.reward_weights):
        raise EnvError(f"reward_weights: {args.reward_weights!r}; give two finite numbers")
    return rules


def safe_name(name: str) -> str:
    """``name`` as one safe file name: no separators, no leading dots (``../x`` -> ``x``)."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("._")
    return cleaned[:100] or "scenario"


@cache
def field_help() -> dict[str, str]:
    """The one-line doc under each :class:`TrainArgs` field (the CLI's help texts)."""
    tree = ast.parse(inspect.getsource(TrainArgs))
    body = tree.body[0].body  # type: ignore[attr-defined]
    out: dict[str, str] = {}
    for node, nxt in zip(body, body[1:], strict=False):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(nxt, ast.Expr)
            and isinstance(nxt.value, ast.Constant)
        ):
            out[node.target.id] = str(nxt.value.value).strip()
    return out


def field_names() -> list[str]:
    return [f.name for f in fields(TrainArgs)]
