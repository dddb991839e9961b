"""Q-networks of the meta-controller: the paper's shape, a compact CPU default, and a small
pooled convolutional one for rollout targets.

A network maps a belt image ``(C, H, W)`` (uint8 occupancy, scaled to [0, 1] inside) and an
optional vector of extra features (the deciding robot's one-hot under parameter sharing) to
one Q-value per action (a dispatching rule, or a joint rule combination). Presets are looked
up by name in :data:`PRESETS`, as Stable-Baselines3 looks up ``"MlpPolicy"``.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import nn


class QNetwork(nn.Module):
    """Convolutional trunk (possibly empty), flatten, concatenate the extras, hidden ReLU
    layers, linear Q head. ``convs`` lists (filters, kernel, stride) per layer."""

    def __init__(
        self,
        obs_shape: tuple[int, int, int],
        n_actions: int,
        n_extra: int,
        convs: list[tuple[int, int, tuple[int, int]]],
        hidden: tuple[int, ...],
        trunk: nn.Sequential | None = None,
    ) -> None:
        super().__init__()
        c, h, w = obs_shape
        layers: list[nn.Module] = []
        for out, kernel, stride in convs:
            layers += [nn.Conv2d(c, out, kernel, stride=stride, padding=kernel // 2), nn.ReLU()]
            c = out
        layers.append(nn.Flatten())
        self.trunk = trunk if trunk is not None else nn.Sequential(*layers)
        with torch.no_grad():
            flat = self.trunk(torch.zeros(1, *obs_shape)).shape[1]
        self.n_extra = n_extra
        head: list[nn.Module] = []
        width = flat + n_extra
        for size in hidden:
            head += [nn.Linear(width, size), nn.ReLU()]
            width = size
        head.append(nn.Linear(width, n_actions))
        self.head = nn.Sequential(*head)

    def forward(self, obs: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        """Q-values ``(B, n_actions)`` for a batch of uint8 or float images ``(B, C, H, W)``."""
        z = self.trunk(obs.float())
        if self.n_extra:
            assert extra is not None, "this network needs the extra features (robot one-hot)"
            z = torch.cat([z, extra.float()], dim=1)
        return self.head(z)


def paper(obs_shape: tuple[int, int, int], n_actions: int, n_extra: int = 0) -> QNetwork:
    """The paper's meta-controller: 3 conv layers, FC 512 ReLU, linear output."""
    convs = [(32, 3, (1, 1)), (64, 3, (1, 2)), (64, 3, (1, 1))]
    return QNetwork(obs_shape, n_actions, n_extra, convs, (512,))


def compact(obs_shape: tuple[int, int, int], n_actions: int, n_extra: int = 0) -> QNetwork:
    """A small network for CPU training: the flattened image, two FC layers of 128 ReLUs.

    No convolution: on a CPU the convolutions' backward pass costs about 4x the whole
    update of this network (measured on the 2-core box), and a robot's window is only
    8 x 7 cells on paper_baseline.
    """
    return QNetwork(obs_shape, n_actions, n_extra, [], (128, 128))


def pooled(obs_shape: tuple[int, int, int], n_actions: int, n_extra: int = 0) -> QNetwork:
    """Two small convolutions with pooling, FC 128: few weights, so it fits noisy regression
    targets (the rollout-trained meta-controller) without memorising cell positions.

    Conv 16 (3 x 5) and max-pool (2 x 4), conv 32 (3 x 3), average-pool to 2 x 8.
    """
    c = obs_shape[0]
    trunk = nn.Sequential(
        nn.Conv2d(c, 16, (3, 5), padding=(1, 2)),
        nn.ReLU(),
        nn.MaxPool2d((2, 4)),
        nn.Conv2d(16, 32, 3, padding=1),
        nn.ReLU(),
        nn.AdaptiveAvgPool2d((2, 8)),
        nn.Flatten(),
    )
    return QNetwork(obs_shape, n_actions, n_extra, [], (128,), trunk)


def student(obs_shape: tuple[int, int, int], n_actions: int, n_extra: int = 0) -> QNetwork:
    """The lookahead's student: the flattened image and the decision features, two FC layers
    of 64 ReLUs. Small enough for the numpy forward pass (a decision in tens of microseconds).
    """
    return QNetwork(obs_shape, n_actions, n_extra, [], (64, 64))


def student_wide(obs_shape: tuple[int, int, int], n_actions: int, n_extra: int = 0) -> QNetwork:
    """The student of the ``student-v2`` to ``-v4`` features (about 180-220 inputs): two FC
    layers of 128 ReLUs, still a numpy forward pass per decision."""
    return QNetwork(obs_shape, n_actions, n_extra, [], (128, 128))


PRESETS: dict[str, Callable[[tuple[int, int, int], int, int], QNetwork]] = {
    "paper": paper,
    "compact": compact,
    "pooled": pooled,
    "student": student,
    "student-wide": student_wide,
}
"""Network preset name -> builder ``(obs_shape, n_actions, n_extra) -> QNetwork``."""


def build_network(
    preset: str, obs_shape: tuple[int, int, int], n_actions: int, n_extra: int = 0
) -> QNetwork:
    """The network for ``preset``; unknown names raise ``ValueError`` listing the presets."""
    try:
        builder = PRESETS[preset]
    except KeyError:
        raise ValueError(
            f"network: '{preset}' is not a preset; allowed {', '.join(PRESETS)}"
        ) from None
    return builder(tuple(obs_shape), n_actions, n_extra)  # type: ignore[arg-type]
