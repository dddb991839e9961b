"""Checkpoints: safetensors weights plus JSON metadata, never pickled code.

A checkpoint folder holds

- ``model.safetensors``: the online Q-network (all that inference needs);
- ``train_state.safetensors``: the target network, the RMSprop state and torch's RNG state;
- ``replay.npz`` (optional): the replay buffer as plain arrays;
- ``meta.json``: what the weights mean (scenario, mode, network preset, rules, observation
  shape, agent config), package versions, step counters and the numpy RNG state.

Every file is written to a temporary name in the same folder and moved into place with
``os.replace``; ``meta.json`` goes last, so a folder whose meta exists is complete. Loading
reads tensors with safetensors and JSON with ``json``: no code is ever unpickled.
"""

from __future__ import annotations

import json
import platform
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load_file, save

from policies.hdqn.agent import AgentConfig, DQNAgent
from twin.errors import UserError
from twin.output import atomic_path, write_text

FORMAT = 1
MODEL = "model.safetensors"
STATE = "train_state.safetensors"
REPLAY = "replay.npz"
META = "meta.json"


class CheckpointError(UserError):
    """A missing or unreadable checkpoint folder; the message is one line."""


def versions() -> dict[str, str]:
    """Versions of what produced the weights."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        twin = version("pnp-twin")
    except PackageNotFoundError:
        twin = "unknown"
    return {
        "pnp_twin": twin,
        "torch": torch.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


def _atomic_json(path: Path, data: dict[str, Any]) -> None:
    write_text(json.dumps(data, indent=2, sort_keys=True) + "\n", path)


def _atomic_tensors(path: Path, tensors: dict[str, torch.Tensor]) -> None:
    with atomic_path(path) as tmp:
        # bytes written into the prepared file keep its usual permissions (save_file's are 0600)
        tmp.write_bytes(save({k: v.detach().cpu().contiguous() for k, v in tensors.items()}))


def save_checkpoint(
    folder: Path,
    agent: DQNAgent,
    meta: dict[str, Any],
    train_state: bool = True,
) -> Path:
    """Write the agent (and, with ``train_state``, what resuming needs) into ``folder``.

    ``meta`` carries the caller's description (scenario, mode, rules, counters, RNG state);
    the agent's shapes, config and the package versions are added here.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    _atomic_tensors(folder / MODEL, {f"q.{k}": v for k, v in agent.q.state_dict().items()})
    opt = agent.optimizer.state_dict()
    if train_state:
        tensors = {f"target.{k}": v for k, v in agent.target.state_dict().items()}
        for idx, state in opt["state"].items():
            for key, value in state.items():
                tensors[f"opt.{idx}.{key}"] = torch.as_tensor(value)
        tensors["rng.torch"] = torch.get_rng_state()
        _atomic_tensors(folder / STATE, tensors)
    full = {
        **meta,
        "format": FORMAT,
        "obs_shape": list(agent.obs_shape),
        "n_actions": agent.n_actions,
        "n_extra": agent.n_extra,
        "agent": asdict(agent.config),
        "updates": agent.updates,
        "optimizer_groups": [
            {k: v for k, v in g.items() if k != "params"} for g in opt["param_groups"]
        ],
        "versions": versions(),
    }
    _atomic_json(folder / META, full)
    return folder


def resolve(folder: str | Path) -> Path:
    """The checkpoint folder itself, or the single run folder inside a training output."""
    path = Path(folder).expanduser()
    if (path / META).is_file():
        return path
    if not path.is_dir():
        raise CheckpointError(f"checkpoint: '{folder}' is not a folder")
    runs = sorted(p.parent for p in path.glob(f"*/{META}"))
    if len(runs) == 1:
        return runs[0]
    if not runs:
        raise CheckpointError(f"checkpoint: '{folder}' holds no {META}; train one first")
    names = ", ".join(p.name for p in runs)
    raise CheckpointError(f"checkpoint: '{folder}' holds several runs ({names}); name one")


def read_meta(folder: str | Path) -> dict[str, Any]:
    """The metadata of a checkpoint folder."""
    path = resolve(folder)
    try:
        meta: dict[str, Any] = json.loads((path / META).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"checkpoint: cannot read {path / META}: {exc}") from None
    if meta.get("format") != FORMAT:
        raise CheckpointError(
            f"checkpoint: {path / META} has format {meta.get('format')}, expected {FORMAT}"
        )
    return meta


def load_agent(
    folder: str | Path, device: str | torch.device = "cpu", train_state: bool = False
) -> tuple[DQNAgent, dict[str, Any]]:
    """Rebuild the agent of a checkpoint; with ``train_state`` also the target, optimizer
    and torch RNG (to resume training)."""
    path = resolve(folder)
    meta = read_meta(path)
    config = AgentConfig(**meta["agent"])
    shape = tuple(meta["obs_shape"])
    agent = DQNAgent(config, shape, meta["n_actions"], meta["n_extra"], device)  # type: ignore[arg-type]
    weights = load_file(str(path / MODEL), device=str(agent.device))
    agent.q.load_state_dict({k[2:]: v for k, v in weights.items() if k.startswith("q.")})
    agent.target.load_state_dict(agent.q.state_dict())
    agent.updates = int(meta.get("updates", 0))
    if train_state:
        _load_train_state(path, agent, meta)
    agent.q.eval()
    return agent, meta


def _load_train_state(path: Path, agent: DQNAgent, meta: dict[str, Any]) -> None:
    if not (path / STATE).is_file():
        raise CheckpointError(f"checkpoint: {path / STATE} is missing; cannot resume")
    tensors = load_file(str(path / STATE))
    agent.target.load_state_dict(
        {k[7:]: v.to(agent.device) for k, v in tensors.items() if k.startswith("target.")}
    )
    state: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in tensors.items():
        if key.startswith("opt."):
            _, idx, name = key.split(".", 2)
            if name != "step":
                value = value.to(agent.device)
            state.setdefault(int(idx), {})[name] = value
    groups = agent.optimizer.state_dict()["param_groups"]
    for group, saved in zip(groups, meta["optimizer_groups"], strict=True):
        group.update(saved)
    agent.optimizer.load_state_dict({"state": state, "param_groups": groups})
    torch.set_rng_state(tensors["rng.torch"])
