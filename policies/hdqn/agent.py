"""The meta-controller: a DQN over dispatching rules with semi-MDP targets.

The hierarchy is the paper's: the meta-controller picks an option (a dispatching rule) for a
free robot; the option's controller then runs it. The controller's only primitive action is
NooP (wait when there is no candidate), and otherwise it applies the chosen rule, which is a
fixed function of the candidates, so the controller is deterministic and has nothing to
learn: only the meta-controller is trained.

Options last a variable simulated time ``tau``, so the one-step target is
``r + gamma ** tau * max_a' Q_target(s', a')`` (``(1 - done)`` masks terminal steps), with
Double DQN (online argmax, target value) optional. Online and target networks, RMSprop, a
Huber loss and a linear epsilon schedule, as in the paper and CleanRL's ``dqn.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from pnp_twin.policies.hdqn.network import QNetwork, build_network


@dataclass(frozen=True)
class Batch:
    """A sampled minibatch, numpy arrays with the batch first."""

    obs: np.ndarray
    extra: np.ndarray
    action: np.ndarray
    reward: np.ndarray
    next_obs: np.ndarray
    next_extra: np.ndarray
    tau: np.ndarray
    done: np.ndarray


@dataclass(frozen=True)
class AgentConfig:
    """Hyper-parameters of the meta-controller (recorded in every checkpoint)."""

    network: str = "compact"  # network preset: compact | paper
    lr: float = 5e-4  # RMSprop learning rate (the paper's 0.01 diverges here)
    gamma: float = 0.9  # discount per simulated second (targets use gamma ** tau)
    double: bool = True  # Double DQN targets
    grad_clip: float = 10.0  # max gradient norm
    target_every: int = 1000  # gradient steps between target-network copies


def linear_epsilon(step: int, start: float, end: float, steps: int) -> float:
    """Epsilon decayed linearly from ``start`` to ``end`` over ``steps``, then held."""
    if steps <= 0:
        return end
    return end + (start - end) * max(0.0, 1.0 - step / steps)


def semi_mdp_targets(
    reward: torch.Tensor,
    tau: torch.Tensor,
    done: torch.Tensor,
    next_q_target: torch.Tensor,
    gamma: float,
    next_q_online: torch.Tensor | None = None,
) -> torch.Tensor:
    """``r + gamma**tau * (1 - done) * Q_target(s', a*)``; a* = argmax of the target's own
    values, or of ``next_q_online`` (Double DQN) when given."""
    if next_q_online is None:
        best = next_q_target.max(dim=1).values
    else:
        a_star = next_q_online.argmax(dim=1, keepdim=True)
        best = next_q_target.gather(1, a_star).squeeze(1)
    return reward + torch.pow(gamma, tau) * (1.0 - done) * best


class DQNAgent:
    """Online and target Q-networks, their optimizer, and the update rule."""

    def __init__(
        self,
        config: AgentConfig,
        obs_shape: tuple[int, int, int],
        n_actions: int,
        n_extra: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        self.config = config
        self.obs_shape = tuple(obs_shape)
        self.n_actions = n_actions
        self.n_extra = n_extra
        self.device = torch.device(device)
        self.q: QNetwork = build_network(config.network, obs_shape, n_actions, n_extra)
        self.q.to(self.device)
        self.target: QNetwork = build_network(config.network, obs_shape, n_actions, n_extra)
        self.target.to(self.device)
        self.target.load_state_dict(self.q.state_dict())
        self.optimizer = torch.optim.RMSprop(self.q.parameters(), lr=config.lr)
        self.updates = 0  # gradient steps taken

    # -- acting -----------------------------------------------------------------------------
    def _tensor(self, a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(a, device=self.device)

    @torch.no_grad()
    def q_values(self, obs: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
        """Q-values ``(B, n_actions)`` for a batch of observations."""
        x = self._tensor(obs)
        e = None if extra is None or not self.n_extra else self._tensor(extra)
        return self.q(x, e).cpu().numpy()

    def greedy(self, obs: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
        """The greedy action per observation of a batch (ties go to the lowest index)."""
        return self.q_values(obs, extra).argmax(axis=1)

    def act(
        self,
        obs: np.ndarray,
        extra: np.ndarray | None,
        epsilon: float,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """Epsilon-greedy actions for a batch; the exploration draws come from ``rng``."""
        actions = self.greedy(obs, extra)
        explore = rng.random(len(actions)) < epsilon
        if explore.any():
            actions[explore] = rng.integers(0, self.n_actions, size=int(explore.sum()))
        return actions

    # -- learning ---------------------------------------------------------------------------
    def update(self, batch: Batch) -> float:
        """One gradient step on a minibatch; returns the TD (Huber) loss."""
        t = self._tensor
        obs, next_obs = t(batch.obs), t(batch.next_obs)
        extra = t(batch.extra) if self.n_extra else None
        next_extra = t(batch.next_extra) if self.n_extra else None
        with torch.no_grad():
            next_target = self.target(next_obs, next_extra)
            next_online = self.q(next_obs, next_extra) if self.config.double else None
            y = semi_mdp_targets(
                t(batch.reward),
                t(batch.tau),
                t(batch.done),
                next_target,
                self.config.gamma,
                next_online,
            )
        q = self.q(obs, extra).gather(1, t(batch.action).unsqueeze(1)).squeeze(1)
        loss = nn.functional.smooth_l1_loss(q, y)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        nn.utils.clip_grad_norm_(self.q.parameters(), self.config.grad_clip)
        self.optimizer.step()
        self.updates += 1
        if self.updates % self.config.target_every == 0:
            self.sync_target()
        return float(loss.item())

    def sync_target(self) -> None:
        """Copy the online weights into the target network."""
        self.target.load_state_dict(self.q.state_dict())


# -- action and input encodings shared by training and inference -----------------------------
def decode_joint(action: int, n_robots: int, n_rules: int) -> list[int]:
    """Rule index per robot of a joint action; robot 0 is the most significant digit, as in
    :class:`pnp_twin.learning.envs.gym_env.PickPlaceEnv`."""
    return [(action // n_rules ** (n_robots - 1 - i)) % n_rules for i in range(n_robots)]


def encode_joint(rules: list[int], n_rules: int) -> int:
    """The joint action of one rule index per robot (inverse of :func:`decode_joint`)."""
    action = 0
    for k in rules:
        action = action * n_rules + int(k)
    return action


def robot_onehot(robots: list[int], n_robots: int) -> np.ndarray:
    """The extra input under parameter sharing: one row per robot, a 1 at its index."""
    out = np.zeros((len(robots), n_robots), dtype=np.float32)
    out[np.arange(len(robots)), robots] = 1.0
    return out
