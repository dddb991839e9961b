"""Training the HDQN meta-controller, top to bottom (in the manner of CleanRL's ``dqn.py``).

One call of :func:`train` is one run named ``scenario__mode__seed``, written to
``out/<run name>/``:

- ``log.csv``: step, episode, reward per step, gripping rate, epsilon, loss, steps/s;
- ``eval.csv``: periodic greedy evaluation on validation seeds, next to every rule;
- ``meta.json`` + ``model.safetensors`` + ``train_state.safetensors`` (+ ``replay.npz``):
  the latest checkpoint, from which ``resume=True`` continues; ``best/``: the weights that
  evaluated best so far (what ``--policy hdqn:DIR`` loads).

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
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.credit import TeamCredit
from pnp_twin.learning.envs.driver import EnvError, EpochDriver, check_rules, intrinsic_reward
from pnp_twin.learning.replay import ReplayBuffer
from pnp_twin.learning.runlog import CsvLog, truncate_log
from policies.hdqn import MODES, TERMINATION
from policies.hdqn.agent import (
    AgentConfig,
    DQNAgent,
    decode_joint,
    linear_epsilon,
    robot_onehot,
)
from policies.hdqn.checkpoint import META, load_agent, save_checkpoint
from policies.rules import RULES
from twin.decision import Policy
from twin.loader import load_scenario, with_overrides
from twin.run import simulate
from twin.scenario import Scenario
from twin.stats import t_interval

log = logging.getLogger(__name__)

TRAIN_SEED_BASE = 1_000_000
VIEWS = ("window", "belt")
"""Multi-agent observations: the robot's workspace window, or the whole belt."""
REWARDS = ("own", "downstream", "team")
"""Multi-agent rewards: eq. 1 + eq. 2 of the robot's option, or team picks during it."""
VALIDATION_SEED_BASE = 500_000


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
    """Discount per simulated second."""
    double: bool = True
    """Double DQN targets."""
    buffer_size: int = 50_000
    """Replay capacity (transitions)."""
    batch_size: int = 64
    """Minibatch size."""
    learning_starts: int = 5_000
    """Transitions collected before the first gradient step."""
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
    reward_weights: tuple[float, float] = (1.0, 1.0)
    """Weights of eq. 1 (picks per second) and eq. 2 (NooP penalty)."""
    noop_penalty: float = 0.01
    """Eq. 2's penalty per NooP."""
    eval_every: int = 20_000
    """Steps between evaluations (and checkpoints)."""
    eval_seeds: int = 4
    """Validation seeds per evaluation."""
    eval_duration: float = 300.0
    """Feeding time of an evaluation run, s (warm-up as in the scenario, capped at 1/5)."""
    log_every: int = 1_000
    """Steps between rows of log.csv."""
    save_replay: bool = False
    """Also checkpoint the replay buffer (larger files; exact resumes)."""
    resume: bool = False
    """Continue the run from its last checkpoint."""
    threads: int = 1
    """torch CPU threads (the machine is shared)."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Dotted-path scenario overrides."""


def resolve_device(device: str) -> torch.device:
    """``auto`` picks CUDA when available, else the CPU."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        return torch.device(device)
    except RuntimeError:
        raise EnvError(f"device: '{device}' is not a device; allowed auto, cpu, cuda") from None


def run_name(scenario: Scenario, mode: str, seed: int) -> str:
    """``scenario__mode__seed``."""
    return f"{scenario.name}__{mode}__{seed}"


def eval_scenario(scenario: Scenario, mode: str, duration: float) -> Scenario:
    """The scenario of evaluation runs: the mode's termination, a shorter feeding time."""
    warmup = min(scenario.warmup, duration / 5.0)
    return with_overrides(
        scenario, {"termination": TERMINATION[mode], "duration": duration, "warmup": warmup}
    )


def rule_baselines(scenario: Scenario, seeds: list[int]) -> dict[str, list[float]]:
    """Gripping rate per seed of every single rule (common random numbers)."""
    from policies.registry import make_policy

    return {
        r: [simulate(scenario, make_policy(r), seed=s).kpis["gripping_rate"] for s in seeds]
        for r in RULES
    }


VALIDATION_COLUMNS = [
    "gripping_rate",
    "diff_vs_best_rule",
    "diff_ci",
    "best_rule",
    "best_rule_gripping_rate",
    "beats_best_rule",
]
"""The figures of one validation (:func:`validate`), the last columns of every eval.csv."""


def validate(
    policy: Policy, scenario: Scenario, seeds: list[int], baselines: dict[str, list[float]]
) -> dict[str, Any]:
    """The greedy ``policy`` on the validation ``seeds`` against the best single rule there
    (``baselines`` from :func:`rule_baselines`; paired, the same seeds for both): the
    :data:`VALIDATION_COLUMNS`. It beats the rule when the paired 95 % interval is above 0."""
    best = max(baselines, key=lambda r: float(np.mean(baselines[r])))
    g = [simulate(scenario, policy, seed=s).kpis["gripping_rate"] for s in seeds]
    diff = np.asarray(g) - np.asarray(baselines[best])
    d_mean, d_low, _ = t_interval(list(diff), 0.95)
    return {
        "gripping_rate": float(np.mean(g)),
        "diff_vs_best_rule": d_mean,
        "diff_ci": d_mean - d_low,
        "best_rule": best,
        "best_rule_gripping_rate": float(np.mean(baselines[best])),
        "beats_best_rule": int(d_low > 0.0),
    }


def train(args: TrainArgs, progress: Callable[[dict[str, Any]], None] | None = None) -> Path:
    """Run one training run; returns its folder. ``progress`` gets a dict every log row."""
    # -- the line, the folder ----------------------------------------------------------------
    if args.mode not in MODES:
        raise EnvError(f"mode: '{args.mode}' is not a mode; allowed {', '.join(MODES)}")
    rules = check_rules(args.rules)
    if args.view not in VIEWS:
        raise EnvError(f"view: '{args.view}' is not a view; allowed {', '.join(VIEWS)}")
    if args.reward not in REWARDS:
        raise EnvError(f"reward: '{args.reward}' is not a reward; allowed {', '.join(REWARDS)}")
    if args.mode == "single" and (args.view, args.reward) != ("window", "own"):
        raise EnvError("view/reward: single mode sees the whole belt with eq. 1 + eq. 2 only")
    base = load_scenario(args.scenario, args.overrides or None)
    termination = TERMINATION[args.mode]
    train_scenario = with_overrides(
        base,
        {"termination": termination, "duration": args.episode_time, "warmup": 0.0},
    )
    folder = Path(args.out) / run_name(base, args.mode, args.seed)
    if (folder / META).is_file() and not args.resume:
        raise EnvError(f"out: {folder} holds a run already; resume it or choose another folder")
    folder.mkdir(parents=True, exist_ok=True)
    device = resolve_device(args.device)
    torch.set_num_threads(max(1, args.threads))

    # -- seeding -----------------------------------------------------------------------------
    random.seed(args.seed)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)

    # -- environment, agent, replay ------------------------------------------------------------
    driver = EpochDriver(
        train_scenario, termination=termination, rules=rules, channels=args.channels
    )
    n, k = driver.n_robots, len(rules)
    multi = args.mode != "single"
    window = multi and args.view == "window"
    obs_shape = driver.camera.window_shape if window else driver.camera.shape
    n_actions = k if multi else k**n
    n_extra = n if multi else 0
    config = AgentConfig(
        args.network, args.lr, args.gamma, args.double, target_every=args.target_every
    )
    agent = DQNAgent(config, obs_shape, n_actions, n_extra, device)
    replay = ReplayBuffer(args.buffer_size, obs_shape, n_extra)
    validation = [VALIDATION_SEED_BASE + i for i in range(args.eval_seeds)]
    val_scenario = eval_scenario(base, args.mode, args.eval_duration)
    counters: dict[str, Any] = {"step": 0, "episode": 0, "wall_time": 0.0, "best_eval": -1.0}

    # -- resume --------------------------------------------------------------------------------
    if args.resume and (folder / META).is_file():
        agent, saved = load_agent(folder, device, train_state=True)
        agent.q.train()
        counters.update(saved["counters"])
        rng.bit_generator.state = saved["rng"]
        if (folder / "replay.npz").is_file():
            replay.load(folder / "replay.npz")
        for name in ("log.csv", "eval.csv"):  # rows logged after the checkpoint are replayed
            truncate_log(folder / name, int(counters["step"]))
        log.info("resumed %s at step %d", folder, counters["step"])

    def meta() -> dict[str, Any]:
        return {
            "name": f"hdqn-{args.mode}",
            "mode": args.mode,
            "view": args.view,
            "termination": termination,
            "rules": list(rules),
            "n_robots": n,
            "scenario": base.model_dump(mode="json"),
            "train_args": {**asdict(args), "rules": list(rules)},
            "device": str(device),
            "counters": dict(counters),
            "rng": rng.bit_generator.state,
        }

    def checkpoint() -> None:
        save_checkpoint(folder, agent, meta())
        if args.save_replay:
            replay.save(folder / "replay.npz")

    # -- evaluation ----------------------------------------------------------------------------
    baselines = rule_baselines(val_scenario, validation)
    eval_log = CsvLog(
        folder / "eval.csv", ["step", "wall_time", *VALIDATION_COLUMNS], append=args.resume
    )

    def evaluate_now() -> None:
        from policies.hdqn.policy import HDQNPolicy

        agent.q.eval()
        row = validate(HDQNPolicy(agent, meta()), val_scenario, validation, baselines)
        agent.q.train()
        eval_log.row(
            [counters["step"], counters["wall_time"], *(row[c] for c in VALIDATION_COLUMNS)]
        )
        mean_g = row["gripping_rate"]
        log.info(
            "step %d: eval G %.2f %% (best rule %s %+.2f +- %.2f)",
            counters["step"],
            mean_g,
            row["best_rule"],
            row["diff_vs_best_rule"],
            row["diff_ci"],
        )
        if mean_g > counters["best_eval"]:
            counters["best_eval"] = mean_g
            save_checkpoint(folder / "best", agent, meta(), train_state=False)
        checkpoint()

    # -- the loop ------------------------------------------------------------------------------
    train_log = CsvLog(
        folder / "log.csv",
        ["step", "episode", "reward_per_step", "gripping_rate", "epsilon", "loss", "steps_per_s"],
        append=args.resume,
    )
    recent_rewards: deque[float] = deque(maxlen=args.log_every)
    losses: deque[float] = deque(maxlen=100)
    last_g = float("nan")
    pending: dict[int, tuple[np.ndarray, np.ndarray | None, int, float]] = {}
    weights, penalty = args.reward_weights, args.noop_penalty
    credit = None if args.reward == "own" else TeamCredit(args.reward, n)

    def reward_of(robot: int) -> float:
        if credit is None:
            return driver.reward(robot, weights, penalty)
        picks = credit.take(robot)
        option = driver.option(robot)
        if option is None:
            return 0.0
        return weights[0] * picks + weights[1] * intrinsic_reward(option, penalty)

    started, logged_at, logged_step = time.perf_counter(), time.perf_counter(), counters["step"]
    wall_before = counters["wall_time"]
    deciding = driver.reset(int(rng.integers(TRAIN_SEED_BASE, 2**31)))
    epsilon = linear_epsilon(
        counters["step"], args.eps_start, args.eps_end, int(args.eps_fraction * args.steps)
    )

    def add(key: int, obs: np.ndarray, extra: np.ndarray | None, reward: float) -> None:
        """Close agent ``key``'s open transition with the observation now; learn."""
        if key not in pending:
            return
        p_obs, p_extra, p_action, p_time = pending.pop(key)
        replay.add(p_obs, p_action, reward, obs, driver.now - p_time, False, p_extra, extra)
        recent_rewards.append(reward)
        counters["step"] += 1
        step = counters["step"]
        if step > args.learning_starts and step % args.train_every == 0:
            losses.append(agent.update(replay.sample(args.batch_size, rng)))

    while counters["step"] < args.steps:
        now = driver.now
        if multi:
            obs = np.stack([driver.observe(r if window else None) for r in deciding])
            extra = robot_onehot(deciding, n)
            for j, r in enumerate(deciding):
                add(r, obs[j], extra[j], reward_of(r))
            chosen = agent.act(obs, extra, epsilon, rng)
            for j, r in enumerate(deciding):
                pending[r] = (obs[j], extra[j], int(chosen[j]), now)
            actions = {r: int(a) for r, a in zip(deciding, chosen, strict=True)}
        else:
            obs1 = driver.observe(None)
            add(0, obs1, None, sum(driver.reward(r, weights, penalty) for r in deciding))
            joint = int(agent.act(obs1[None], None, epsilon, rng)[0])
            pending[0] = (obs1, None, joint, now)
            per_robot = decode_joint(joint, n, k)
            actions = {r: per_robot[r] for r in deciding}
        deciding = driver.act(actions)
        if credit is not None:
            credit.add(driver.step_picks, pending)
        epsilon = linear_epsilon(
            counters["step"], args.eps_start, args.eps_end, int(args.eps_fraction * args.steps)
        )
        if driver.done:  # a time limit, not a terminal state: open transitions are dropped
            last_g = driver.gripping_rate()
            counters["episode"] += 1
            pending.clear()
            if credit is not None:
                credit.clear()
            deciding = driver.reset(int(rng.integers(TRAIN_SEED_BASE, 2**31)))
        step = counters["step"]
        if step - logged_step >= args.log_every or step >= args.steps:
            t = time.perf_counter()
            sps = (step - logged_step) / max(t - logged_at, 1e-9)
            logged_at, logged_step = t, step
            counters["wall_time"] = wall_before + (t - started)
            reward = float(np.mean(recent_rewards)) if recent_rewards else 0.0
            loss = float(np.mean(losses)) if losses else float("nan")
            g = last_g if last_g == last_g else driver.gripping_rate()
            train_log.row([step, counters["episode"], reward, g, epsilon, loss, sps])
            if progress is not None:
                progress(
                    {
                        "step": step,
                        "total": args.steps,
                        "steps_per_s": sps,
                        "reward": reward,
                        "gripping_rate": g,
                        "epsilon": epsilon,
                        "loss": loss,
                        "episode": counters["episode"],
                    }
                )
            if step % args.eval_every < args.log_every or step >= args.steps:
                evaluate_now()
    train_log.close()
    eval_log.close()
    return folder
