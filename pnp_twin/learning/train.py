"""Training the HDQN meta-controller, top to bottom (in the manner of CleanRL's ``dqn.py``).

One call of :func:`train` is one run named ``scenario__mode__seed``, written to
``out/<run name>/``:

- ``log.csv``: step, episode, reward per step, gripping rate, epsilon, loss, steps/s;
- ``eval.csv``: periodic greedy evaluation on validation seeds, next to every rule;
- ``meta.json`` + ``model.safetensors``: the latest weights; ``best/``: the weights that
  evaluated best so far (what ``--policy hdqn:DIR`` loads);
- ``resume/``: the exact state of the loop at the last checkpoint
  (:mod:`pnp_twin.learning.resume`), from which ``resume=True`` continues: a run stopped at
  any point (Ctrl-C, SIGTERM or SIGKILL) and resumed ends with the same weights, byte for
  byte, as one never stopped. SIGINT and SIGTERM write a checkpoint before stopping
  (:class:`TrainingInterrupted`).

Modes (:data:`policies.hdqn.MODES`):

- ``single``: one agent sees the whole belt and picks a joint action, ``Discrete(K**N)``;
  t_continue, so each step only the free robots use their component; the step reward is the
  sum of the rewards of the options that ended.
- ``sync``: one agent per robot with shared parameters (centralised training, decentralised
  execution); each sees its workspace window and its one-hot index; t_all.
- ``async``: as ``sync`` under t_continue: the paper's hierarchical multi-agent set-up.

Two options for the multi-agent modes (the defaults are the paper's and those of the shipped
checkpoints; a checkpoint without them in its ``train_args`` reads as the defaults):

- ``view``: ``window`` (each agent sees its workspace window, partial observability) or
  ``belt`` (each agent sees the whole belt image plus its one-hot index: centralised
  observations, still decentralised execution, allowed by the CTDE framing);
- ``reward``: ``own`` (eq. 1 + eq. 2 of the robot's own option), or team credit for the
  option: ``downstream`` counts the picks completed during the option by the robot and every
  robot downstream of it (the only robots its choice can affect; upstream picks do not
  depend on it), ``team`` by every robot; eq. 2's NooP penalty is added in both. The
  discounted sum of these counts is the discounted number of parts gripped, which is what
  the gripping rate G measures (eq. 1 per robot instead rewards each robot's own rate, whose
  optimum is the greedy per-robot rule, SPT). Weighted by ``reward_weights`` as eq. 1/eq. 2.

A step is one meta-controller transition (one robot's decision in ``sync``/``async``, one
epoch in ``single``). Seeds: training episodes use seeds >= 1,000,000 drawn from the run's
generator; periodic evaluation uses validation seeds 500,000 + i; ``pnp-twin evaluate``
defaults to seeds 0..n-1, so all three sets are disjoint.
"""

from __future__ import annotations

import logging
import random
import signal
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.credit import TeamCredit
from pnp_twin.learning.dqn_update import DQNAgent, linear_epsilon
from pnp_twin.learning.envs.driver import EnvError, EpochDriver, intrinsic_reward
from pnp_twin.learning.replay import ReplayBuffer
from pnp_twin.learning.resume import RESUME, LoopState, load_state, resume_folder, save_state
from pnp_twin.learning.runlog import CsvLog, truncate_log
from pnp_twin.learning.train_args import (
    REWARDS,
    VIEWS,
    TrainArgs,
    check_args,
    safe_name,
    settled,
)
from pnp_twin.learning.train_checkpoint import save_checkpoint
from pnp_twin.learning.validation import (
    VALIDATION_COLUMNS,
    VALIDATION_SEED_BASE,
    eval_scenario,
    rule_baselines,
    validate,
    validation_seeds,
)
from pnp_twin.policies.hdqn import TERMINATION
from pnp_twin.policies.hdqn.agent import AgentConfig, decode_joint, robot_onehot
from pnp_twin.policies.hdqn.checkpoint import META
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

TRAIN_SEED_BASE = 1_000_000
LOG_COLUMNS = [
    "step",
    "episode",
    "reward_per_step",
    "gripping_rate",
    "epsilon",
    "loss",
    "steps_per_s",
]

__all__ = [
    "REWARDS",
    "TRAIN_SEED_BASE",
    "VALIDATION_COLUMNS",
    "VALIDATION_SEED_BASE",
    "VIEWS",
    "TrainArgs",
    "TrainingInterrupted",
    "eval_scenario",
    "resolve_device",
    "rule_baselines",
    "run_name",
    "train",
    "validate",
]


class TrainingInterrupted(UserError):
    """SIGINT or SIGTERM stopped the run after it wrote a checkpoint; resume continues."""

    def __init__(self, folder: Path, step: int) -> None:
        super().__init__(
            f"interrupted at step {step}; the checkpoint in {folder} is complete: "
            "run the same command with --resume to continue"
        )
        self.folder, self.step = folder, step


def resolve_device(device: str) -> torch.device:
    """``auto`` picks CUDA when available, else the CPU."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        return torch.device(device)
    except RuntimeError:
        raise EnvError(f"device: '{device}' is not a device; allowed auto, cpu, cuda") from None


def run_name(scenario: Scenario, mode: str, seed: int) -> str:
    """``scenario__mode__seed``, the scenario's name reduced to a safe file name."""
    return f"{safe_name(scenario.name)}__{mode}__{seed}"


def run_folder(out: str | Path, name: str) -> Path:
    """``out/name``, refused if it would lie outside ``out``."""
    root = Path(out).resolve()
    folder = (root / name).resolve()
    if folder.parent != root:
        raise EnvError(f"out: the run name {name!r} leaves {root}; rename the scenario")
    return Path(out) / name


@dataclass
class Setup:
    """The pieces of a run the loop works on (built once, before the loop)."""

    args: TrainArgs
    driver: EpochDriver
    agent: DQNAgent
    replay: ReplayBuffer
    credit: TeamCredit | None
    rng: np.random.Generator
    multi: bool
    window: bool


def train(args: TrainArgs, progress: Callable[[dict[str, Any]], None] | None = None) -> Path:
    """Run one training run; returns its folder. ``progress`` gets a dict every log row."""
    # -- settings, the line, the folder --------------------------------------------------------
    args = settled(args)
    rules = check_args(args)
    base = load_scenario(args.scenario, args.overrides or None)
    termination = TERMINATION[args.mode]
    train_scenario = with_overrides(
        base, {"termination": termination, "duration": args.episode_time, "warmup": 0.0}
    )
    folder = run_folder(args.out, run_name(base, args.mode, args.seed))
    started_before = (folder / META).is_file() or resume_folder(folder) is not None
    if started_before and not args.resume:
        raise EnvError(f"out: {folder} holds a run already; resume it or choose another folder")
    resuming = args.resume and resume_folder(folder) is not None
    folder.mkdir(parents=True, exist_ok=True)
    device = resolve_device(args.device)
    torch.set_num_threads(max(1, args.threads))

    # -- seeding -------------------------------------------------------------------------------
    random.seed(args.seed)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)

    # -- environment, agent, replay --------------------------------------------------------------
    driver = EpochDriver(
        train_scenario, termination=termination, rules=rules, channels=args.channels
    )
    n, k = driver.n_robots, len(rules)
    multi = args.mode != "single"
    window = multi and args.view == "window"
    obs_shape = driver.camera.window_shape if window else driver.camera.shape
    config = AgentConfig(
        args.network, args.lr, args.gamma, args.double, target_every=args.target_every
    )
    agent = DQNAgent(config, obs_shape, k if multi else k**n, n if multi else 0, device)
    replay = ReplayBuffer(args.buffer_size, obs_shape, n if multi else 0)
    credit = None if args.reward == "own" else TeamCredit(args.reward, n)
    loop = LoopState(log_every=int(args.log_every or 1))

    # -- resume, or a first episode --------------------------------------------------------------
    if resuming:
        agent = load_state(folder, device, replay, loop, driver, credit, rng)
        log.info("resumed %s at step %d", folder, loop.step)
    else:
        driver.reset(int(rng.integers(TRAIN_SEED_BASE, 2**31)))
    run = Setup(args, driver, agent, replay, credit, rng, multi, window)
    meta = _meta_fields(args, base, rules, device)
    if resuming:  # rows written after the checkpoint are written again
        for name in ("log.csv", "eval.csv"):
            truncate_log(folder / name, loop.step)
    train_log = CsvLog(folder / "log.csv", LOG_COLUMNS, append=resuming)
    eval_log = CsvLog(
        folder / "eval.csv", ["step", "wall_time", *VALIDATION_COLUMNS], append=resuming
    )
    validation = validation_seeds(args.eval_seeds)
    val_scenario = eval_scenario(base, args.mode, args.eval_duration)
    ran: set[str] = set()
    baselines = rule_baselines(val_scenario, validation, args.engine, ran)
    ran_text = ",".join(sorted(ran))  # the engine that ran the rule baselines, recorded
    meta = {**meta, "train_args": {**meta["train_args"], "baseline_engine": ran_text}}

    # -- the loop --------------------------------------------------------------------------------
    clock = _Clock(loop.step, loop.wall_time)
    with _stop_on_signals() as stop:
        while loop.step < args.steps:
            before = loop.step
            epsilon = linear_epsilon(
                loop.step, args.eps_start, args.eps_end, int(args.eps_fraction * args.steps)
            )
            _decide_and_learn(run, loop, epsilon)
            if driver.done:  # a time limit, not a terminal state: open transitions are dropped
                _next_episode(run, loop)
            last = loop.step >= args.steps
            if _crossed(before, loop.step, args.log_every) or last:
                row = _log_row(run, loop, clock, epsilon)
                train_log.row([row[c] for c in LOG_COLUMNS])
                if progress is not None:
                    progress({**row, "total": args.steps, "reward": row["reward_per_step"]})
            evaluated = _crossed(before, loop.step, args.eval_every) or last
            if evaluated:
                loop.wall_time = clock.wall_time()
                scores = _evaluate(
                    run,
                    loop,
                    {**meta, "counters": loop.counters()},
                    val_scenario,
                    validation,
                    baselines,
                    folder,
                )
                eval_log.row([loop.step, loop.wall_time, *(scores[c] for c in VALIDATION_COLUMNS)])
            if evaluated or stop.requested or _crossed(before, loop.step, args.checkpoint_every):
                loop.wall_time = clock.wall_time()
                _checkpoint(run, loop, {**meta, "counters": loop.counters()}, folder)
            if stop.requested and not last:
                train_log.close()
                eval_log.close()
                raise TrainingInterrupted(folder, loop.step)
    train_log.close()
    eval_log.close()
    return folder


# -- the steps of the loop ---------------------------------------------------------------------
def _decide_and_learn(run: Setup, loop: LoopState, epsilon: float) -> None:
    """At one decision epoch: close the options that ended (store and learn from them),
    choose the deciding robots' rules epsilon-greedily, run the twin to the next epoch."""
    driver, agent, args = run.driver, run.agent, run.args
    deciding, now = driver.deciding, driver.now
    if run.multi:
        obs = np.stack([driver.observe(r if run.window else None) for r in deciding])
        extra = robot_onehot(deciding, driver.n_robots)
        for j, r in enumerate(deciding):
            _close(run, loop, r, obs[j], extra[j], _reward(run, r))
        chosen = agent.act(obs, extra, epsilon, run.rng)
        for j, r in enumerate(deciding):
            loop.pending[r] = (obs[j], extra[j], int(chosen[j]), now)
        actions = {r: int(a) for r, a in zip(deciding, chosen, strict=True)}
    else:
        weights, penalty = args.reward_weights, args.noop_penalty
        belt = driver.observe(None)
        _close(run, loop, 0, belt, None, sum(driver.reward(r, weights, penalty) for r in deciding))
        joint = int(agent.act(belt[None], None, epsilon, run.rng)[0])
        loop.pending[0] = (belt, None, joint, now)
        per_robot = decode_joint(joint, driver.n_robots, len(driver.rules))
        actions = {r: per_robot[r] for r in deciding}
    driver.act(actions)
    if run.credit is not None:
        run.credit.add(driver.step_picks, loop.pending)


def _reward(run: Setup, robot: int) -> float:
    """The reward of ``robot``'s option that just ended: eq. 1 + eq. 2, or team credit."""
    weights, penalty = run.args.reward_weights, run.args.noop_penalty
    if run.credit is None:
        return run.driver.reward(robot, weights, penalty)
    picks = run.credit.take(robot)
    option = run.driver.option(robot)
    if option is None:
        return 0.0
    return weights[0] * picks + weights[1] * intrinsic_reward(option, penalty)


def _close(
    run: Setup,
    loop: LoopState,
    key: int,
    obs: np.ndarray,
    extra: np.ndarray | None,
    reward: float,
) -> None:
    """Close agent ``key``'s open transition with the observation now; maybe learn."""
    if key not in loop.pending:
        return
    p_obs, p_extra, p_action, p_time = loop.pending.pop(key)
    tau = run.driver.now - p_time
    run.replay.add(p_obs, p_action, reward, obs, tau, False, p_extra, extra)
    loop.rewards.append(reward)
    loop.step += 1
    args = run.args
    if loop.step > (args.learning_starts or 0) and loop.step % args.train_every == 0:
        loop.losses.append(run.agent.update(run.replay.sample(args.batch_size, run.rng)))


def _next_episode(run: Setup, loop: LoopState) -> None:
    loop.last_g = run.driver.gripping_rate()
    loop.episode += 1
    loop.pending.clear()
    if run.credit is not None:
        run.credit.clear()
    run.driver.reset(int(run.rng.integers(TRAIN_SEED_BASE, 2**31)))


def _crossed(before: int, after: int, every: int | None) -> bool:
    """True when the step counter passed a multiple of ``every`` (steps jump by the number
    of robots deciding together, so 'is a multiple' would miss some)."""
    return bool(every) and after // every > before // every  # type: ignore[operator]


class _Clock:
    """Steps per second between log rows, and the run's wall time across resumes."""

    def __init__(self, step: int, wall_before: float) -> None:
        self.started = self.at = time.perf_counter()
        self.step, self.wall_before = step, wall_before

    def rate(self, step: int) -> float:
        t = time.perf_counter()
        sps = (step - self.step) / max(t - self.at, 1e-9)
        self.at, self.step = t, step
        return sps

    def wall_time(self) -> float:
        return self.wall_before + (time.perf_counter() - self.started)


def _log_row(run: Setup, loop: LoopState, clock: _Clock, epsilon: float) -> dict[str, Any]:
    loop.wall_time = clock.wall_time()
    g = loop.last_g if loop.last_g == loop.last_g else run.driver.gripping_rate()
    return {
        "step": loop.step,
        "episode": loop.episode,
        "reward_per_step": float(np.mean(loop.rewards)) if loop.rewards else 0.0,
        "gripping_rate": g,
        "epsilon": epsilon,
        "loss": float(np.mean(loop.losses)) if loop.losses else float("nan"),
        "steps_per_s": clock.rate(loop.step),
    }


def _evaluate(
    run: Setup,
    loop: LoopState,
    meta: dict[str, Any],
    scenario: Scenario,
    seeds: list[int],
    baselines: dict[str, list[float]],
    folder: Path,
) -> dict[str, Any]:
    """Validate the greedy policy; keep its weights in ``best/`` when it is the best yet."""
    from pnp_twin.policies.hdqn.policy import HDQNPolicy

    run.agent.q.eval()
    scores = validate(HDQNPolicy(run.agent, meta), scenario, seeds, baselines, run.args.engine)
    run.agent.q.train()
    log.info(
        "step %d: eval G %.2f %% (best rule %s %+.2f +- %.2f)",
        loop.step,
        scores["gripping_rate"],
        scores["best_rule"],
        scores["diff_vs_best_rule"],
        scores["diff_ci"],
    )
    if scores["gripping_rate"] > loop.best_eval:
        loop.best_eval = scores["gripping_rate"]
        meta = {**meta, "counters": loop.counters()}
        save_checkpoint(folder / "best", run.agent, meta, train_state=False)
    return scores


def _checkpoint(run: Setup, loop: LoopState, meta: dict[str, Any], folder: Path) -> None:
    """The exact resume state first, then the latest weights for inference."""
    replay = run.replay if run.args.save_replay else None
    save_state(folder, run.agent, meta, replay, loop, run.driver, run.credit, run.rng)
    save_checkpoint(folder, run.agent, meta, train_state=False)
    log.debug("checkpoint at step %d in %s/%s", loop.step, folder, RESUME)


def _meta_fields(
    args: TrainArgs, base: Scenario, rules: tuple[str, ...], device: torch.device
) -> dict[str, Any]:
    """What a checkpoint says about the run (the agent's own fields are added on save)."""
    return {
        "name": f"hdqn-{args.mode}",
        "mode": args.mode,
        "view": args.view,
        "termination": TERMINATION[args.mode],
        "rules": list(rules),
        "n_robots": base.robots.count,
        "scenario": base.model_dump(mode="json"),
        "train_args": {**asdict(args), "rules": list(rules)},
        "device": str(device),
    }


class _StopFlag:
    requested = False


@contextmanager
def _stop_on_signals() -> Iterator[_StopFlag]:
    """SIGINT / SIGTERM ask the loop to checkpoint and stop (main thread only)."""
    import threading

    flag = _StopFlag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def ask(signum: int, _frame: Any) -> None:
        if flag.requested and signum == signal.SIGINT:  # a second Ctrl-C: stop now
            raise KeyboardInterrupt
        flag.requested = True
        log.warning("signal %d: checkpointing, then stopping", signum)

    changed = {}
    for s in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(s) is not signal.SIG_IGN:  # pool workers leave Ctrl-C to the caller
            changed[s] = signal.signal(s, ask)
    try:
        yield flag
    finally:
        for s, old in changed.items():
            signal.signal(s, old)
