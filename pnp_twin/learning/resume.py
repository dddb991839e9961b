"""The exact state of a training run: written at every checkpoint, read by ``--resume``.

A run folder's ``resume/`` holds everything the training loop carries, so that a resumed run
continues as if it had never stopped and ends with byte-identical weights:

- the agent (:func:`pnp_twin.learning.train_checkpoint.save_checkpoint` with the train state: online
  and target weights, the RMSprop state, torch's RNG state) and its ``meta.json``;
- ``replay.npz``: the replay buffer (plain arrays);
- ``loop.npz``: the open transitions (one per agent whose option is running), the team
  credit, the recent rewards and losses (what the next log row averages), and the actions of
  the episode so far (the driver is rebuilt by replaying them on the episode's seed);
- ``state.json``: the loop's counters and the numpy and Python RNG states.

The folder is written whole under a temporary name, then swapped in (the previous one is
kept as ``resume.old`` until the swap is done), so a kill at any instant leaves one complete
state behind. Nothing is unpickled on load: arrays with ``allow_pickle=False``, JSON.
"""

from __future__ import annotations

import json
import logging
import math
import random
import shutil
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.credit import TeamCredit
from pnp_twin.learning.dqn_update import DQNAgent
from pnp_twin.learning.envs.driver import EpochDriver
from pnp_twin.learning.replay import ReplayBuffer
from pnp_twin.learning.train_checkpoint import load_trainer, save_checkpoint
from pnp_twin.policies.hdqn.checkpoint import CheckpointError
from pnp_twin.twin.output import atomic_path, write_text

log = logging.getLogger(__name__)

RESUME = "resume"
OLD = "resume.old"

Pending = tuple[np.ndarray, np.ndarray | None, int, float]
"""An open transition: observation, extra features, action, simulated time of the decision."""


@dataclass
class LoopState:
    """What the training loop carries from one decision epoch to the next."""

    log_every: int
    step: int = 0
    episode: int = 0
    wall_time: float = 0.0
    best_eval: float = -1.0
    last_g: float = math.nan
    pending: dict[int, Pending] = field(default_factory=dict)
    rewards: deque[float] = field(default_factory=deque)
    losses: deque[float] = field(default_factory=lambda: deque(maxlen=100))

    def __post_init__(self) -> None:
        self.rewards = deque(self.rewards, maxlen=self.log_every)

    def counters(self) -> dict[str, Any]:
        return {
            "step": self.step,
            "episode": self.episode,
            "wall_time": self.wall_time,
            "best_eval": self.best_eval,
        }


def resume_folder(run: Path) -> Path | None:
    """The complete resume state of a run folder, or None when there is none."""
    for name in (RESUME, OLD):
        if (run / name / "state.json").is_file():
            return run / name
    return None


def save_state(
    run: Path,
    agent: DQNAgent,
    meta: dict[str, Any],
    replay: ReplayBuffer | None,
    loop: LoopState,
    driver: EpochDriver,
    credit: TeamCredit | None,
    rng: np.random.Generator,
) -> Path:
    """Write ``run/resume/`` (see the module docstring) and swap it in; without ``replay``
    (``--no-save-replay``) a resume starts from an empty buffer and is not exact."""
    tmp = run / f".{RESUME}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    save_checkpoint(tmp, agent, meta, train_state=True)
    if replay is not None:
        replay.save(tmp / "replay.npz")
    _save_loop(tmp / "loop.npz", loop, driver, credit)
    state = {
        "counters": {**loop.counters(), "last_g": loop.last_g},
        "numpy_rng": rng.bit_generator.state,
        "python_rng": list(random.getstate()),
        "episode_seed": driver.seed,
    }
    write_text(json.dumps(state), tmp / "state.json")
    current, old = run / RESUME, run / OLD
    if current.exists():
        shutil.rmtree(old, ignore_errors=True)
        current.rename(old)
    tmp.rename(current)
    shutil.rmtree(old, ignore_errors=True)
    return current


def load_state(
    run: Path,
    device: torch.device,
    replay: ReplayBuffer,
    loop: LoopState,
    driver: EpochDriver,
    credit: TeamCredit | None,
    rng: np.random.Generator,
) -> DQNAgent:
    """Restore everything :func:`save_state` wrote into the given objects; the agent."""
    folder = resume_folder(run)
    if folder is None:
        raise CheckpointError(f"checkpoint: {run} has no {RESUME}/ state to resume from")
    agent, _meta = load_trainer(folder, device, train_state=True)
    agent.q.train()
    try:
        state = json.loads((folder / "state.json").read_text())
        if (folder / "replay.npz").is_file():
            replay.load(folder / "replay.npz")
        else:
            log.warning("%s holds no replay buffer (--no-save-replay): not an exact resume", run)
        history = _load_loop(folder / "loop.npz", loop, credit)
    except (OSError, ValueError, KeyError) as e:
        raise CheckpointError(f"checkpoint: cannot resume from {folder}: {e}") from None
    counters = state["counters"]
    loop.step, loop.episode = int(counters["step"]), int(counters["episode"])
    loop.wall_time, loop.best_eval = float(counters["wall_time"]), float(counters["best_eval"])
    loop.last_g = float(counters["last_g"])
    rng.bit_generator.state = state["numpy_rng"]
    version, internal, gauss = state["python_rng"]
    random.setstate((version, tuple(internal), gauss))
    driver.replay(int(state["episode_seed"]), history)
    return agent


def _save_loop(path: Path, loop: LoopState, driver: EpochDriver, credit: TeamCredit | None) -> None:
    keys = sorted(loop.pending)
    pending = [loop.pending[k] for k in keys]
    history = driver.history
    arrays: dict[str, Any] = {
        "pending_key": np.asarray(keys, dtype=np.int64),
        "pending_action": np.asarray([p[2] for p in pending], dtype=np.int64),
        "pending_time": np.asarray([p[3] for p in pending], dtype=np.float64),
        "rewards": np.asarray(loop.rewards, dtype=np.float64),
        "losses": np.asarray(loop.losses, dtype=np.float64),
        "credit": np.asarray(credit.picks if credit else [], dtype=np.int64),
        "history_len": np.asarray([len(a) for a in history], dtype=np.int64),
        "history_robot": np.asarray([r for a in history for r in a], dtype=np.int64),
        "history_action": np.asarray([k for a in history for k in a.values()], dtype=np.int64),
    }
    if pending:
        arrays["pending_obs"] = np.stack([p[0] for p in pending])
        if pending[0][1] is not None:
            arrays["pending_extra"] = np.stack([p[1] for p in pending])  # type: ignore[misc]
    with atomic_path(path) as tmp, tmp.open("wb") as f:
        np.savez(f, **arrays)  # type: ignore[arg-type]


def _load_loop(path: Path, loop: LoopState, credit: TeamCredit | None) -> list[dict[int, int]]:
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    loop.pending = {}
    for j, key in enumerate(data["pending_key"].tolist()):
        extra = data["pending_extra"][j] if "pending_extra" in data else None
        loop.pending[int(key)] = (
            data["pending_obs"][j],
            extra,
            int(data["pending_action"][j]),
            float(data["pending_time"][j]),
        )
    loop.rewards = deque(data["rewards"].tolist(), maxlen=loop.log_every)
    loop.losses = deque(data["losses"].tolist(), maxlen=100)
    if credit is not None:
        credit.picks = [int(v) for v in data["credit"]]
    history: list[dict[int, int]] = []
    robots, actions = data["history_robot"].tolist(), data["history_action"].tolist()
    at = 0
    for n in data["history_len"].tolist():
        history.append(dict(zip(robots[at : at + n], actions[at : at + n], strict=True)))
        at += n
    return history
