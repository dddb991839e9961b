"""Experience replay: a numpy ring buffer of semi-MDP transitions.

Each transition is ``(obs, extra, action, reward, next_obs, next_extra, tau, done)``:
``tau`` is the simulated time the option took (seconds), so the target discounts by
``gamma ** tau``; ``extra`` holds the deciding robot's one-hot under parameter sharing
(zero-width otherwise). Images are stored as uint8, so 10,000 transitions of a (2, 8, 64)
belt take about 20 MB.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pnp_twin.learning.dqn_update import Batch

FIELDS = ("obs", "extra", "action", "reward", "next_obs", "next_extra", "tau", "done")


class ReplayBuffer:
    """Fixed-capacity ring buffer; once full, each new transition overwrites the oldest."""

    def __init__(self, capacity: int, obs_shape: tuple[int, ...], n_extra: int = 0) -> None:
        if capacity < 1:
            raise ValueError(f"replay: capacity must be at least 1, got {capacity}")
        self.capacity = capacity
        self.obs = np.zeros((capacity, *obs_shape), dtype=np.uint8)
        self.next_obs = np.zeros((capacity, *obs_shape), dtype=np.uint8)
        self.extra = np.zeros((capacity, n_extra), dtype=np.float32)
        self.next_extra = np.zeros((capacity, n_extra), dtype=np.float32)
        self.action = np.zeros(capacity, dtype=np.int64)
        self.reward = np.zeros(capacity, dtype=np.float32)
        self.tau = np.zeros(capacity, dtype=np.float32)
        self.done = np.zeros(capacity, dtype=np.float32)
        self.pos = 0  # next slot to write
        self.size = 0  # transitions held
        self.added = 0  # transitions ever added

    def __len__(self) -> int:
        return self.size

    def add(
        self,
        obs: np.ndarray,
        action: int,
        reward: float,
        next_obs: np.ndarray,
        tau: float,
        done: bool,
        extra: np.ndarray | None = None,
        next_extra: np.ndarray | None = None,
    ) -> None:
        """Store one transition in the next slot."""
        i = self.pos
        self.obs[i] = obs
        self.next_obs[i] = next_obs
        if extra is not None:
            self.extra[i] = extra
        if next_extra is not None:
            self.next_extra[i] = next_extra
        self.action[i] = action
        self.reward[i] = reward
        self.tau[i] = tau
        self.done[i] = float(done)
        self.pos = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)
        self.added += 1

    def sample(self, batch_size: int, rng: np.random.Generator) -> Batch:
        """A uniform minibatch (with replacement) drawn from ``rng``."""
        idx = rng.integers(0, self.size, size=batch_size)
        return Batch(*(getattr(self, f)[idx] for f in FIELDS))

    # -- persistence (plain arrays, loaded with allow_pickle=False) -------------------------
    def save(self, path: Path) -> None:
        """Write the buffer to ``path`` (an .npz) atomically."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        counters = np.array([self.pos, self.size, self.added], dtype=np.int64)
        np.savez(tmp, counters=counters, **{f: getattr(self, f) for f in FIELDS})
        tmp.replace(path)

    def load(self, path: Path) -> None:
        """Restore a buffer written by :meth:`save` (same capacity and shapes)."""
        with np.load(Path(path), allow_pickle=False) as data:
            for f in FIELDS:
                arr = data[f]
                if arr.shape != getattr(self, f).shape:
                    raise ValueError(
                        f"replay: saved {f} has shape {arr.shape}, expected "
                        f"{getattr(self, f).shape}"
                    )
                getattr(self, f)[...] = arr
            self.pos, self.size, self.added = (int(v) for v in data["counters"])
