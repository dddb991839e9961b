"""Training the async meta-controller on rollout targets (``pnp-twin train --targets rollout``).

Rounds: label ``round_episodes`` more episodes (:func:`pnp_twin.learning.rollout.label_episode`,
in worker processes), fit the Q-network to all labels so far (mean squared error on the
advantage of every rule over the base rule; Adam; the ``pooled`` network by default), then
evaluate the greedy policy on the validation seeds against every single rule, as
:func:`pnp_twin.learning.train.train` does. The run folder ``out/<scenario>__async__<seed>/``
holds ``labels.npz`` (the labels and the episodes they came from; a rerun with ``resume``
labels only the missing episodes), ``eval.csv`` (one row per round: ``step``, the labels so
far, the episodes, the wall time, the validation gripping rate, and
whether the policy beats the best rule outside the paired 95 % interval), and the checkpoint
(``meta.json`` + ``model.safetensors``), loadable with ``--policy hdqn:DIR`` like any other:
the agents see the whole belt (parts, claimed parts) and their one-hot index, and decide
asynchronously (t_continue).

Determinism: the labels depend only on the scenario, the episode seeds and the settings;
the fit on the labels and the run's seed. The same seed gives the same checkpoint whatever
the number of workers. An interrupted run loses at most the round it was labelling.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.dqn_update import DQNAgent
from pnp_twin.learning.envs.driver import EnvError
from pnp_twin.learning.rollout import Labels, LabelSettings, label_episode
from pnp_twin.learning.runlog import CsvLog, truncate_log
from pnp_twin.learning.train import (
    VALIDATION_COLUMNS,
    VALIDATION_SEED_BASE,
    eval_scenario,
    resolve_device,
    rule_baselines,
    run_name,
    validate,
)
from pnp_twin.learning.train_checkpoint import save_checkpoint
from pnp_twin.parallel import pool_map_ordered
from pnp_twin.policies.hdqn.agent import AgentConfig
from pnp_twin.policies.hdqn.checkpoint import META
from pnp_twin.policies.hdqn.policy import HDQNPolicy
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.output import atomic_path
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

PRELOAD = ("pnp_twin.learning.rollout",)
"""Modules the labelling workers' forkserver imports once (they never import torch)."""
EPISODE_SEED_BASE = 2_000_000
"""Rollout episodes of run seed s use seeds 2,000,000 + 10,000 s + i (disjoint from the
validation seeds 500,000 + i and from ``pnp-twin evaluate``'s 0..n-1)."""


@dataclass
class RolloutArgs:
    """Everything a rollout-trained run depends on (recorded in its checkpoint)."""

    scenario: str = "paper_baseline"
    out: str = "runs"
    seed: int = 1
    """Seed of the run: episode seeds and the network's initialisation and minibatches."""
    episodes: int = 600
    """Labelled episodes in all."""
    round_episodes: int = 100
    """Episodes labelled between two fits (and evaluations)."""
    workers: int = 1
    """Processes labelling episodes."""
    settings: LabelSettings = field(default_factory=LabelSettings)
    network: str = "pooled"
    epochs: int = 30
    lr: float = 1e-3
    weight_decay: float = 1e-4
    batch_size: int = 256
    device: str = "auto"
    eval_seeds: int = 4
    eval_duration: float = 300.0
    resume: bool = False
    overrides: dict[str, Any] = field(default_factory=dict)
    engine: str = "auto"
    """Engine of the labelling rollouts and the validation runs (same results on each)."""


def _label(job: tuple[Scenario, int, LabelSettings, str]) -> Labels:
    """Worker entry point (labelling runs the twin only: no torch)."""
    return label_episode(*job)


def fit(labels: Labels, args: RolloutArgs, n_robots: int, device: torch.device) -> DQNAgent:
    """A fresh agent whose Q-network regresses the labels' advantages (seeded by the run)."""
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    k = labels.advantage.shape[1]
    config = AgentConfig(args.network, args.lr, 0.0, False)
    agent = DQNAgent(config, tuple(labels.obs.shape[1:]), k, n_robots, device)  # type: ignore[arg-type]
    net = agent.q
    opt = torch.optim.Adam(net.parameters(), lr=args.lr, weight_decay=args.weight_decay)
    obs = torch.as_tensor(labels.obs, device=device)
    extra = torch.eye(n_robots, device=device)[torch.as_tensor(labels.robot, device=device)]
    target = torch.as_tensor(labels.advantage, dtype=torch.float32, device=device)
    net.train()
    for _ in range(args.epochs):
        order = torch.as_tensor(rng.permutation(len(labels)), device=device)
        for i in range(0, len(labels), args.batch_size):
            b = order[i : i + args.batch_size]
            loss = ((net(obs[b], extra[b]) - target[b]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    net.eval()
    agent.target.load_state_dict(net.state_dict())
    return agent


def _save_labels(path: Path, labels: Labels, done: int) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(
            f, obs=labels.obs, robot=labels.robot, advantage=labels.advantage, done=done
        )


def _load_labels(path: Path) -> tuple[Labels, int]:
    with np.load(path) as z:
        return Labels(z["obs"], z["robot"], z["advantage"]), int(z["done"])


def train_rollout(
    args: RolloutArgs, progress: Callable[[dict[str, Any]], None] | None = None
) -> Path:
    """Run one rollout-trained run; returns its folder. ``progress`` gets a dict per round."""
    args.settings.check()
    rules = list(args.settings.rules)
    base = load_scenario(args.scenario, args.overrides or None)
    scenario = with_overrides(base, {"termination": "t_continue", "warmup": 0.0})
    folder = Path(args.out) / run_name(base, "async", args.seed)
    if (folder / META).is_file() and not args.resume:
        raise EnvError(f"out: {folder} holds a run already; resume it or choose another folder")
    folder.mkdir(parents=True, exist_ok=True)
    device = resolve_device(args.device)
    n = base.robots.count
    labels_path = folder / "labels.npz"
    parts: list[Labels] = []
    done = 0
    if args.resume and labels_path.is_file():
        loaded, done = _load_labels(labels_path)
        parts.append(loaded)
        log.info("resumed %s with %d labelled episodes", folder, done)
    validation = [VALIDATION_SEED_BASE + i for i in range(args.eval_seeds)]
    val_scenario = eval_scenario(base, "async", args.eval_duration)
    ran: set[str] = set()
    baselines = rule_baselines(val_scenario, validation, args.engine, ran)
    # "step" counts labelled decisions (the transitions of this training), as in train's eval.csv
    columns = ["step", "episodes", "wall_time", *VALIDATION_COLUMNS]
    resuming = bool(parts)  # a resume with no labels yet starts the logs afresh
    if resuming:  # rows of rounds after the saved labels come again
        truncate_log(folder / "eval.csv", len(parts[0]))
    eval_log = CsvLog(folder / "eval.csv", columns, append=resuming)
    t0 = time.perf_counter()
    while done < args.episodes:
        upto = min(args.episodes, done + args.round_episodes)
        seeds = [EPISODE_SEED_BASE + 10_000 * args.seed + i for i in range(done, upto)]
        jobs = [(scenario, e, args.settings, args.engine) for e in seeds]
        # results in episode order, so the labels do not depend on the worker count
        if args.workers > 1:
            parts.extend(pool_map_ordered(_label, jobs, args.workers, PRELOAD))
        else:
            parts.extend(map(_label, jobs))
        labels = Labels.concat(parts)
        parts = [labels]
        done = upto
        _save_labels(labels_path, labels, done)
        agent = fit(labels, args, n, device)
        meta = {
            "name": "hdqn-async",
            "mode": "async",
            "view": "belt",
            "termination": "t_continue",
            "targets": "rollout",
            "rules": list(rules),
            "n_robots": n,
            "scenario": base.model_dump(mode="json"),
            "train_args": {
                **asdict(args),
                "view": "belt",
                "mode": "async",
                "baseline_engine": ",".join(sorted(ran)),  # the engine of the rule baselines
            },
            "device": str(device),
            "counters": {
                "step": len(labels),
                "episodes": done,
                "wall_time": time.perf_counter() - t0,
            },
        }
        save_checkpoint(folder, agent, meta, train_state=False)
        row = {
            "step": len(labels),
            "episodes": done,
            "wall_time": time.perf_counter() - t0,
            **validate(HDQNPolicy(agent, meta), val_scenario, validation, baselines, args.engine),
        }
        eval_log.row([row[c] for c in columns])
        log.info(
            "%d episodes: G %.2f %% (%s %+.2f)",
            done,
            row["gripping_rate"],
            row["best_rule"],
            row["diff_vs_best_rule"],
        )
        if progress is not None:
            progress(row)
    eval_log.close()
    return folder
