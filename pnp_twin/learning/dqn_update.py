"""Training the meta-controller: a DQN over dispatching rules with semi-MDP targets.

Options last a variable simulated time ``tau``, so the one-step target is
``r + gamma ** tau * max_a' Q_target(s', a')`` (``(1 - done)`` masks terminal steps), with
Double DQN (online argmax, target value) optional. Online and target networks, RMSprop, a
Huber loss and a linear epsilon schedule, as in the paper and CleanRL's ``dqn.py``.

:class:`DQNAgent` is the inference agent (:class:`pnp_twin.policies.hdqn.agent.QAgent`, which
is all a trained policy needs) plus what learning adds: the target network, the optimizer,
exploration and the update rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from pnp_twin.policies.hdqn.agent import AgentConfig, QAgent
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


class DQNAgent(QAgent):
    """Online and target Q-networks, their optimizer, and the update rule."""

    def __init__(
        self,
        config: AgentConfig,
        obs_shape: tuple[int, int, int],
        n_actions: int,
        n_extra: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        super().__init__(config, obs_shape, n_actions, n_extra, device)  # the online network
        self.target: QNetwork = build_network(config.network, obs_shape, n_actions, n_extra)
        self.target.to(self.device)
        self.target.load_state_dict(self.q.state_dict())
        self.optimizer = torch.optim.RMSprop(self.q.parameters(), lr=config.lr)
        self.updates = 0  # gradient steps taken

    # -- acting -----------------------------------------------------------------------------
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
