"""The trained HDQN as a policy like any other: ``--policy hdqn:DIR``.

:class:`HDQNPolicy` is a :class:`~policies.base.RuleChoosingPolicy`: at each decision it
draws the same observation the training environment drew (with the environment's own
:class:`~twin.camera.BeltCamera`), asks the Q-network for the greedy rule and lets
that rule pick the part. :data:`policies.registry.PREFIXED` names :func:`from_spec` for the
``hdqn`` prefix; it needs torch (the ``learn`` extra).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.policies.base import RuleChoosingPolicy
from pnp_twin.policies.hdqn.agent import QAgent, decode_joint, robot_onehot
from pnp_twin.policies.hdqn.checkpoint import (
    META,
    CheckpointError,
    load_agent,
    resolve,
    warn_if_other_line,
)
from pnp_twin.policies.hdqn.features import ANY_COUNT, DecisionFeatures
from pnp_twin.policies.hdqn.numpy_forward import NumpyQ, Unsupported
from pnp_twin.policies.hdqn.ranges import training_ranges, warn_outside
from pnp_twin.twin.belt import Belt
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

_NO_IMAGE = np.zeros((1, 0, 1, 1), np.uint8)
"""The image of a student that sees its decision features only."""


def camera_scenario(base: dict[str, Any], belt: Belt, robots: list[RobotSpec]) -> Scenario:
    """The trained scenario with the live line's belt and workspaces (what the camera uses)."""
    data = dict(base)
    data["belt"] = {
        **base.get("belt", {}),
        "length": belt.length,
        "width": belt.width,
        "speed": belt.speed,
        "grid": list(belt.grid),
    }
    data["robots"] = {
        **base.get("robots", {}),
        "count": len(robots),
        "workspaces": [list(r.workspace) for r in robots],
        "arm_speed": max(r.arm_speed for r in robots),
        "overrides": [],
    }
    data.pop("sweep", None)
    return Scenario.model_validate(data)


class HDQNPolicy(RuleChoosingPolicy):
    """Greedy rule choice of a trained meta-controller (see the module docstring).

    ``mode`` is the training set-up: ``async``/``sync`` agents see the deciding robot's
    workspace window plus its one-hot index (or, trained with ``view = "belt"``, the whole
    belt plus the one-hot); a ``single`` agent sees the whole belt and picks a joint action,
    of which the deciding robot uses its own component.

    Decisions run the network's forward pass in numpy (:class:`NumpyQ`, the weights copied
    from the agent when a run starts) and take torch's greedy action, proven so; a near tie
    between two actions' values, a network on another device, or ``numpy_forward=False``
    asks torch.
    """

    def __init__(self, agent: QAgent, meta: dict[str, Any], numpy_forward: bool = True) -> None:
        super().__init__()
        self.agent = agent
        self.meta = meta
        self.mode: str = meta["mode"]
        self.rules: list[str] = list(meta["rules"])
        self.channels = int(agent.obs_shape[0])
        # checkpoints from before the view option saw windows in the multi-agent modes
        view = meta.get("view", meta.get("train_args", {}).get("view", "window"))
        self.whole_belt: bool = self.mode == "single" or view == "belt"
        self.sees_image: bool = view != "none"  # a student may see its features only
        self.name = meta.get("name", f"hdqn-{self.mode}")
        self.camera: BeltCamera | None = None
        self._decisions = 0  # a fresh image per decision (claims change between them)
        self.numpy_forward = numpy_forward
        self._numpy: NumpyQ | None = None
        self._input = np.ones(1, np.float32)  # a student's first-layer input (features, 1)
        self.torch_decisions = 0  # decisions torch ranked (near ties, or no numpy forward)
        # a student of the lookahead controller also sees decision features (its extras)
        features = meta.get("features")
        self.features = None if features is None else DecisionFeatures(features, self.rules)
        self.any_count: bool = features in ANY_COUNT
        """A student for any robot count and order (per-robot scoring, shared weights)."""
        self.ranges = training_ranges(meta) if self.features is not None else None
        self._rate: float | None = None

    @classmethod
    def load(cls, folder: str | Path, device: str = "cpu") -> HDQNPolicy:
        """The policy of a checkpoint folder (or a training output holding one run).

        A training run's folder holds its latest weights and, in ``best/``, the weights
        that evaluated best on the validation seeds: those are loaded when present.
        """
        import torch

        # One small network per decision: extra intra-op threads only cost (and they
        # oversubscribe the cores when sweeps run one policy per worker process).
        torch.set_num_threads(1)
        path = resolve(folder)
        if (path / "best" / META).is_file():
            path = path / "best"
        agent, meta = load_agent(path, device)
        return cls(agent, meta)

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        super().reset(robots, rng)
        self._rate = None
        if self.features is not None:
            self.features.reset(self.robots)
        self._numpy = self._numpy_q()
        if self._numpy is not None:
            self._input = np.ones(self._numpy.n_in, np.float32)
        n = int(self.meta["n_robots"])
        if len(robots) != n and not self.any_count:
            raise CheckpointError(
                f"policy: the HDQN was trained for {n} robots, the line has {len(robots)}"
            )

    def bind_run(self, scenario: Scenario, seed: int, duration: float) -> None:
        """The run's scenario (called by the line after ``reset``): the decision features
        take the feeder's nominal rate from it."""
        if self.features is not None:
            self.features.reset(self.robots, float(scenario.feeder.rate))
        if self.ranges is not None:
            warn_outside(self.ranges, scenario, self.robots, f"the HDQN ({self.name})")

    def attach(self, belt: Belt) -> None:
        """Called by the line with its belt: build the camera for this line's geometry."""
        if self.features is not None:
            self.features.attach(belt)
        if not self.sees_image:
            self.camera = None
            return
        scenario = camera_scenario(self.meta["scenario"], belt, self.robots)
        camera = BeltCamera(scenario, self.channels)
        camera.attach(belt)
        want = tuple(self.agent.obs_shape)
        got = camera.shape if self.whole_belt else camera.window_shape
        if tuple(got) != want:
            raise CheckpointError(
                f"policy: this line gives observations of shape {tuple(got)}, the HDQN was "
                f"trained on {want}; use a line with the trained belt grid and workspace size"
            )
        if self.ranges is None:  # one training line: a line unlike it is warned of here
            warn_if_other_line(self.meta, belt, self.robots, f"the HDQN ({self.name})")
        self.camera = camera

    def observe(self, decision: Decision) -> tuple[np.ndarray, np.ndarray | None]:
        """The network input for a decision: (1, C, H, W) image and the extra features."""
        obs = self.image(decision)
        if self.mode == "single":
            return obs, None
        if self.features is not None:
            return obs, self.features.vector(decision)[None]
        return obs, robot_onehot([decision.robot], len(self.robots))

    def image(self, decision: Decision) -> np.ndarray:
        """The (1, C, H, W) image a decision shows the network (C = 0: a student that sees
        its features only)."""
        if not self.sees_image:
            return _NO_IMAGE
        camera = self.camera
        if camera is None:
            raise RuntimeError("HDQNPolicy needs the belt: the line calls attach(belt)")
        now, robot, free = decision.time, decision.robot, (decision.robot,)
        if self.mode == "single":
            return camera.belt(now, free)[None]
        self._decisions += 1
        if self.whole_belt:
            return camera.belt(now, free)[None]
        return camera.window(robot, now, free, self._decisions)[None]

    def choose(self, decision: Decision) -> int:
        """The part the greedy rule picks. A student of the lookahead computes every rule's
        pick once (its features need them) and, as the lookahead does, asks its network only
        when the rules disagree (when they agree the decision counts under its first rule)."""
        features = self.features
        if features is None or "SIRO" in self.rules:
            return super().choose(decision)
        picks = features.picks(decision)
        first = picks[0]
        if all(p == first for p in picks):
            self.last_rule = self.rules[0]
            return first
        fast = self._numpy
        if not self.sees_image and fast is not None and fast.compiled:
            # the features straight into the first layer's input (its last entry stays 1)
            x = self._input
            features.vector(decision, picks, out=x[:-1])
            action = fast.greedy_input(x)
            if action is None:
                action = self._torch_greedy(_NO_IMAGE, x[None, :-1].copy())
        else:
            action = self._greedy(self.image(decision), features.vector(decision, picks)[None])
        self.last_rule = self.rules[action]
        return picks[action]

    def _greedy(self, obs: np.ndarray, extra: np.ndarray | None) -> int:
        action = None if self._numpy is None else self._numpy.greedy(obs, extra)
        return self._torch_greedy(obs, extra) if action is None else action

    def _torch_greedy(self, obs: np.ndarray, extra: np.ndarray | None) -> int:
        """Torch's greedy action (a near tie the numpy pass left, or no numpy pass)."""
        self.torch_decisions += 1
        return int(self.agent.greedy(obs, extra)[0])

    def _numpy_q(self) -> NumpyQ | None:
        """The numpy forward of the agent's current weights, when it can stand in for torch
        (a CPU network of supported layers)."""
        if not self.numpy_forward or self.agent.device.type != "cpu":
            return None
        try:
            # a student's decisions must cost a small share of its teacher's: one compiled call
            return NumpyQ(self.agent.q, compiled=self.features is not None)
        except Unsupported:
            return None

    def select_rule(self, decision: Decision) -> str:
        obs, extra = self.observe(decision)
        action = self._greedy(obs, extra)
        if self.mode == "single":
            action = decode_joint(action, len(self.robots), len(self.rules))[decision.robot]
        return self.rules[action]


def from_spec(arg: str) -> HDQNPolicy:
    """``hdqn:DIR``: the checkpoint in DIR (or the newest run under it)."""
    if not arg:
        raise CheckpointError("policy: hdqn needs a folder, e.g. hdqn:runs/paper_baseline")
    return HDQNPolicy.load(arg)
