"""The meta-controller at inference: its Q-network and the greedy rule choice.

The hierarchy is the paper's: the meta-controller picks an option (a dispatching rule) for a
free robot; the option's controller then runs it. The controller's only primitive action is
NooP (wait when there is no candidate), and otherwise it applies the chosen rule, which is a
fixed function of the candidates, so the controller is deterministic and has nothing to
learn: only the meta-controller is trained.

This module holds what inference needs: the hyper-parameters a checkpoint records
(:class:`AgentConfig`), the online network with its greedy action (:class:`QAgent`) and the
action and input encodings shared with training. Training (the target network, the
optimizer, the semi-MDP update, epsilon-greedy exploration, the replay buffer and saving
checkpoints) is on the learning floor: :mod:`pnp_twin.learning.dqn_update`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from pnp_twin.policies.hdqn.network import QNetwork, build_network


@dataclass(frozen=True)
class AgentConfig:
    """Hyper-parameters of the meta-controller (recorded in every checkpoint)."""

    network: str = "compact"  # network preset: compact | paper
    lr: float = 5e-4  # RMSprop learning rate (the paper's 0.01 diverges here)
    gamma: float = 0.9  # discount per simulated second (targets use gamma ** tau)
    double: bool = True  # Double DQN targets
    grad_clip: float = 10.0  # max gradient norm
    target_every: int = 1000  # gradient steps between target-network copies


class QAgent:
    """The online Q-network of a meta-controller and its greedy action."""

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
