"""A trained IPPO / MAPPO actor as a policy like any other: ``--policy marl:DIR``.

``DIR`` holds what :func:`pnp_twin.learning.marl_checkpoint.save_marl` writes: the actor's
weights (``model.safetensors``: the shared per-agent network of TorchRL's ``MultiAgentMLP``,
two tanh layers) and ``meta.json`` (task, algorithm, rules, agents, window shape, whether
the policy is masked). At each decision :class:`MarlPolicy` draws the deciding robot's
workspace window with the env's own :class:`~twin.camera.BeltCamera`, appends its one-hot
id (and, masked, the action mask: every rule, since a robot the line asks has a candidate),
and takes the actor's most likely rule, whose pick it makes. Inference needs torch only,
not TorchRL. A checkpoint is checked before use (known keys and types, every tensor with
its shape, finite); a broken one is one ``checkpoint:`` line.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.policies.base import RuleChoosingPolicy
from pnp_twin.policies.hdqn.checkpoint import (
    CheckpointError,
    check_weights,
    flush_subnormals,
    read_tensors,
)
from pnp_twin.policies.registry import rule_names
from pnp_twin.twin.belt import Belt
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.inputs import SCENARIO_BYTES, read_user_text
from pnp_twin.twin.scenario import Scenario

KIND = "marl"
META = "meta.json"
MODEL = "model.safetensors"
REQUIRED = {
    "format": int,
    "kind": str,
    "algo": str,
    "task": str,
    "rules": list,
    "n_agents": int,
    "window": list,
    "masked": bool,
    "hidden": int,
    "depth": int,
    "scenario": dict,
}


def read_meta(folder: Path) -> dict[str, Any]:
    """``meta.json`` of a marl checkpoint, checked (one CheckpointError line if not)."""
    path = folder / META
    if not path.exists():
        raise CheckpointError(f"checkpoint: {path} is missing; give a folder saved by save_marl")
    text = read_user_text(path, "checkpoint", SCENARIO_BYTES, CheckpointError)  # the guard
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as e:
        raise CheckpointError(f"checkpoint: cannot read {path}: {str(e).splitlines()[0]}") from None
    if not isinstance(meta, dict):
        raise CheckpointError(f"checkpoint: {path}: must be a JSON object")
    for key, kind in REQUIRED.items():
        if not isinstance(meta.get(key), kind) or (kind is int and isinstance(meta[key], bool)):
            raise CheckpointError(f"checkpoint: {path}: {key}: missing or not a {kind.__name__}")
    if meta["kind"] != KIND or meta["format"] != 1:
        raise CheckpointError(f"checkpoint: {path}: not a marl checkpoint (kind 'marl', format 1)")
    try:
        meta["rules"] = list(rule_names(meta["rules"]))
    except ValueError as e:
        raise CheckpointError(f"checkpoint: {path}: rules: {e}") from None
    if not 1 <= meta["n_agents"] <= 64 or not 1 <= meta["hidden"] <= 4096 or meta["depth"] != 2:
        raise CheckpointError(f"checkpoint: {path}: n_agents, hidden or depth out of range")
    if len(meta["window"]) != 3 or not all(isinstance(x, int) and x > 0 for x in meta["window"]):
        raise CheckpointError(f"checkpoint: {path}: window: give [C, H, w], each >= 1")
    return meta


def input_size(meta: dict[str, Any]) -> int:
    c, h, w = meta["window"]
    return c * h * w + meta["n_agents"] + (len(meta["rules"]) if meta["masked"] else 0)


class MarlPolicy(RuleChoosingPolicy):
    """The greedy rule of a trained IPPO / MAPPO actor (see the module docstring)."""

    def __init__(self, net: Any, meta: dict[str, Any]) -> None:
        super().__init__()
        self.net = net
        self.meta = meta
        self.rules: list[str] = list(meta["rules"])
        self.n_agents = int(meta["n_agents"])
        self.name = meta.get("name") or f"marl-{meta['algo']}"
        self.camera: BeltCamera | None = None
        self._scenario: Scenario | None = None
        self._input = np.zeros(input_size(meta), np.float32)
        self._decisions = 0

    @classmethod
    def load(cls, folder: str | Path) -> MarlPolicy:
        import torch
        from torch import nn

        torch.set_num_threads(1)
        path = Path(folder).expanduser()
        meta = read_meta(path)
        k, hidden = len(meta["rules"]), meta["hidden"]
        net = nn.Sequential(
            nn.Linear(input_size(meta), hidden), nn.Tanh(),
            nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, k),
        )  # fmt: skip
        expected = {f"actor.{n}": v for n, v in net.state_dict().items()}
        tensors = read_tensors(path / MODEL)
        check_weights(tensors, expected, str(path / MODEL))
        tensors = flush_subnormals(tensors)
        net.load_state_dict({n.removeprefix("actor."): v for n, v in tensors.items()})
        net.eval()
        return cls(net, meta)

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        super().reset(robots, rng)
        if len(robots) != self.n_agents:
            raise CheckpointError(
                f"policy: the marl policy was trained for {self.n_agents} robots, the line "
                f"has {len(robots)}"
            )

    def bind_run(self, scenario: Scenario, seed: int, duration: float) -> None:
        self._scenario = scenario

    def attach(self, belt: Belt) -> None:
        if self._scenario is None:
            raise RuntimeError("MarlPolicy needs the run's scenario: the line calls bind_run")
        camera = BeltCamera(self._scenario, int(self.meta["window"][0]))
        if list(camera.window_shape) != list(self.meta["window"]):
            raise CheckpointError(
                f"policy: this line gives windows of shape {camera.window_shape}, the marl "
                f"policy was trained on {tuple(self.meta['window'])}; use the trained grid"
            )
        camera.attach(belt)
        self.camera = camera

    def select_rule(self, decision: Decision) -> str:
        import torch

        camera = self.camera
        if camera is None:
            raise RuntimeError("MarlPolicy needs the belt: the line calls attach(belt)")
        self._decisions += 1
        window = camera.window(decision.robot, decision.time, (decision.robot,), self._decisions)
        x = self._input
        x[:] = 0.0
        size = window.size
        x[:size] = window.reshape(-1)
        x[size + decision.robot] = 1.0
        if self.meta["masked"]:
            x[size + self.n_agents :] = 1.0  # a robot the line asks has a candidate
        with torch.no_grad():
            logits = self.net(torch.from_numpy(x))
        return self.rules[int(logits.argmax())]

    def act_env(self, obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Greedy rules for the multi-agent vector env's arrays: ``obs`` (lines, agents, C,
        H, w), ``mask`` (lines, agents, K) -> (lines, agents) rule indices (the input the
        actor was trained on; for :func:`pnp_twin.learning.marl_eval.rates`)."""
        import torch

        e, n = obs.shape[0], self.n_agents
        parts = [obs.reshape(e, n, -1).astype(np.float32),
                 np.broadcast_to(np.eye(n, dtype=np.float32), (e, n, n))]  # fmt: skip
        if self.meta["masked"]:
            parts.append(mask.astype(np.float32))
        with torch.no_grad():
            logits = self.net(torch.from_numpy(np.concatenate(parts, axis=-1)))
        if self.meta["masked"]:
            logits = logits.masked_fill(~torch.from_numpy(mask.astype(bool)), -torch.inf)
        return logits.argmax(-1).numpy()


def from_spec(arg: str) -> MarlPolicy:
    """``marl:DIR``: the IPPO / MAPPO checkpoint in DIR."""
    if not arg:
        raise CheckpointError("policy: marl needs a folder, e.g. marl:runs/ippo_baseline")
    return MarlPolicy.load(arg)
