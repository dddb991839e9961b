"""Writing checkpoints, and reading one back to resume training.

The format is :mod:`pnp_twin.policies.hdqn.checkpoint`'s (which reads a checkpoint for
inference): ``model.safetensors`` (the online network), with ``train_state`` also
``train_state.safetensors`` (the target network, the RMSprop state and torch's RNG state),
and ``meta.json`` last. Every file is written to a temporary name in the same folder and
moved into place with ``os.replace``.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch
from safetensors.torch import save

from pnp_twin.learning.dqn_update import DQNAgent
from pnp_twin.policies.hdqn.checkpoint import (
    FORMAT,
    META,
    MODEL,
    STATE,
    CheckpointError,
    check_weights,
    flush_subnormals,
    load_into,
    read_tensors,
    resolve,
)
from pnp_twin.twin.output import atomic_path, write_text
from pnp_twin.twin.output import versions as package_versions


def versions() -> dict[str, str]:
    """Versions of what produced the weights."""
    return package_versions("pnp-twin", "torch", "numpy")


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
    online = {f"q.{k}": v for k, v in agent.q.state_dict().items()}
    # inference reads model.safetensors, flushed; resuming reads the exact weights (online.*)
    _atomic_tensors(folder / MODEL, flush_subnormals(online))
    opt = agent.optimizer.state_dict()
    if train_state:
        tensors = {f"online.{k}": v for k, v in online.items()}
        tensors.update({f"target.{k}": v for k, v in agent.target.state_dict().items()})
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


def load_trainer(
    folder: str | Path, device: str | torch.device = "cpu", train_state: bool = True
) -> tuple[DQNAgent, dict[str, Any]]:
    """Rebuild the training agent of a checkpoint: the online weights copied into the target;
    with ``train_state`` the target, optimizer and torch RNG as saved (to resume training)."""
    path = resolve(folder)
    agent, meta = load_into(DQNAgent, path, device, flush=not train_state)
    agent.target.load_state_dict(agent.q.state_dict())
    agent.updates = int(meta.get("updates", 0))
    if train_state:
        _load_train_state(path, agent, meta)
    return agent, meta


def _load_train_state(path: Path, agent: DQNAgent, meta: dict[str, Any]) -> None:
    if not (path / STATE).is_file():
        raise CheckpointError(f"checkpoint: {path / STATE} is missing; cannot resume")
    tensors = read_tensors(path / STATE)
    online = {k[7:]: v for k, v in tensors.items() if k.startswith("online.")}
    if online:  # the exact online weights (model.safetensors has its subnormals flushed)
        check_weights(online, {f"q.{k}": v for k, v in agent.q.state_dict().items()}, str(path))
        agent.q.load_state_dict({k[2:]: v.to(agent.device) for k, v in online.items()})
    target = {f"target.{k}": v for k, v in agent.target.state_dict().items()}
    check_weights(
        {k: v for k, v in tensors.items() if k.startswith("target.")}, target, str(path / STATE)
    )
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
