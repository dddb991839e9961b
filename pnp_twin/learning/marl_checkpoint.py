"""Saving a trained IPPO / MAPPO actor as a checkpoint ``--policy marl:DIR`` runs.

:func:`save_marl` writes, into a folder, ``model.safetensors`` (the actor's shared per-agent
network, subnormals flushed), ``meta.json`` (what :mod:`pnp_twin.policies.marl_policy`
checks and needs: task, algorithm, rules, agents, window shape, masked, the network's size,
the task's line as a scenario, the training settings and counters, package versions), each
file written to a temporary name and moved into place, ``meta.json`` last.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

from safetensors.torch import save

from pnp_twin.learning.marl_ppo import TrainResult
from pnp_twin.learning.tasks import get_task
from pnp_twin.policies.hdqn.checkpoint import flush_subnormals
from pnp_twin.policies.marl_policy import META, MODEL, MarlPolicy
from pnp_twin.twin.output import atomic_path, write_text
from pnp_twin.twin.output import versions as package_versions


def save_marl(result: TrainResult, folder: str | Path, name: str = "") -> Path:
    """Write ``result``'s actor as a ``marl:`` checkpoint into ``folder``; returns it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cfg = result.config
    feats = result.policy.features
    mlp = result.policy.actor.module[0].module  # TensorDictModule -> MultiAgentMLP
    weights = {f"actor.{k.removeprefix('params.')}": v for k, v in mlp.state_dict().items()}
    weights = flush_subnormals({k: v.detach().cpu().contiguous() for k, v in weights.items()})
    with atomic_path(folder / MODEL) as tmp:
        tmp.write_bytes(save(weights))
    task = get_task(cfg.task)
    window = [int(x) for x in feats.window_shape]
    meta: dict[str, Any] = {
        "format": 1,
        "kind": "marl",
        "name": name or folder.name,
        "algo": cfg.algo,
        "task": task.name,
        "rules": list(cfg.rules),
        "n_agents": feats.n,
        "window": window,
        "masked": cfg.masked,
        "hidden": cfg.hidden,
        "depth": 2,
        "scenario": task.line(cfg.duration).model_dump(mode="json"),
        "config": asdict(cfg),
        "counters": {
            "env_steps": result.env_steps,
            "sim_seconds": result.sim_seconds,
            "wall_s": result.wall_s,
            "cpu_s": result.cpu_s,
        },  # fmt: skip
        "versions": package_versions("pnp-twin", "torch", "torchrl", "numpy"),
    }
    write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n", folder / META)
    MarlPolicy.load(folder)  # what was written loads and checks
    return folder


__all__ = ["save_marl"]
