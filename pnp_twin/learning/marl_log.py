"""Training logs of a multi-agent run: a CSV file and, optionally, TensorBoard.

:class:`TrainLog` is the ``progress`` callback of :func:`pnp_twin.learning.marl_ppo.train`:
every training row (per update: env steps, reward per simulated second, the loss terms,
episodes ended, the training lines' G, and ``eval_G``, the greedy policy's G on short
evaluation runs at fixed step intervals, where one fell in the update) goes to
``progress.csv`` in ``folder`` (columns fixed by :data:`COLUMNS`, flushed each row: readable
while training) and, with ``tensorboard=True``, to TensorBoard event files there (scalars
under ``train/`` and ``eval/``, step = env steps). TensorBoard needs ``tensorboardX`` or
``torch.utils.tensorboard`` (the ``tensorboard`` extra); without either it is one
:class:`~pnp_twin.learning.marl_ppo.MarlError` line.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from pnp_twin.learning.marl_ppo import MarlError
from pnp_twin.learning.runlog import CsvLog

COLUMNS = [
    "env_steps",
    "iteration",
    "reward_per_s",
    "episodes",
    "train_G",
    "eval_G",
    "eval_G_low",
    "eval_G_high",
    "loss_objective",
    "loss_critic",
    "loss_entropy",
    "entropy",
    "wall_s",
]


def summary_writer(folder: Path) -> Any:
    """A TensorBoard writer (tensorboardX, else torch's), or one MarlError line."""
    try:
        from tensorboardX import SummaryWriter
    except ImportError:
        try:
            from torch.utils.tensorboard import SummaryWriter  # type: ignore[no-redef]
        except ImportError:
            raise MarlError(
                "tensorboard: needs tensorboardX; install it: pip install 'pnp-twin[tensorboard]'"
            ) from None
    return (
        SummaryWriter(logdir=str(folder))
        if "tensorboardX" in SummaryWriter.__module__
        else (SummaryWriter(log_dir=str(folder)))
    )


class TrainLog:
    """Rows to ``folder/progress.csv`` and, with ``tensorboard``, TensorBoard (see the module
    docstring)."""

    def __init__(self, folder: str | Path, tensorboard: bool = False) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.csv = CsvLog(self.folder / "progress.csv", COLUMNS, append=False)
        self.writer = summary_writer(self.folder) if tensorboard else None

    def __call__(self, row: dict[str, float]) -> None:
        self.csv.row([_cell(row.get(c)) for c in COLUMNS])
        if self.writer is None:
            return
        step = int(row["env_steps"])
        for key, value in row.items():
            if key in ("env_steps", "iteration") or value is None or math.isnan(value):
                continue
            group = "eval" if key.startswith("eval_") else "train"
            self.writer.add_scalar(f"{group}/{key}", float(value), step)
        self.writer.flush()

    def close(self) -> None:
        self.csv.close()
        if self.writer is not None:
            self.writer.close()


def _cell(value: float | None) -> Any:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return float(value)


__all__ = ["COLUMNS", "TrainLog", "summary_writer"]
