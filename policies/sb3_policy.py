"""A Stable-Baselines3 model trained on ``pnp_twin/PickPlace-v0`` as a policy: ``sb3:MODEL.zip``.

``pnp-twin run``, ``sweep``, ``size`` and ``evaluate`` take ``--policy sb3:MODEL.zip`` (a
model saved with ``model.save(...)``, loaded with PPO, DQN or A2C, whichever fits). At each
decision the policy draws the observation the environment would give at that instant (the
whole belt image; a 0/255 image upscaled when the model was trained with
``observation="image"``), asks the model for its deterministic action and lets the rule the
action gives the deciding robot pick the part: a ``Discrete(K**N)`` joint action (robot 1
the most significant digit) or a ``MultiDiscrete`` one. Rule index k means the k-th of
``FIFO LIFO SIRO SD LD SPT`` (the environment's default rules are the first five); for a
model trained with other rules name them: ``sb3:MODEL.zip@SPT,FIFO``.

Loading an SB3 zip unpickles Python objects: load only models you trust. Needs
stable-baselines3 (the ``test`` extra, or ``pip install stable-baselines3``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.policies.base import RuleChoosingPolicy
from pnp_twin.policies.registry import PolicyError, rule_names
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.belt import Belt
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.inputs import MODEL_BYTES, check_user_file
from pnp_twin.twin.scenario import Scenario

ALGORITHMS = ("PPO", "DQN", "A2C")


def load_model(path: Path) -> Any:
    """The SB3 model saved at ``path``: the first of :data:`ALGORITHMS` that loads it."""
    try:
        import stable_baselines3 as sb3
    except ImportError:
        raise PolicyError(
            "policy: sb3: needs stable-baselines3; install it: pip install stable-baselines3"
        ) from None
    if not path.exists():
        raise PolicyError(f"policy: sb3: '{path}' is not a file; give a model saved by SB3")
    check_user_file(path, "policy: sb3", MODEL_BYTES, PolicyError)
    errors = []
    for name in ALGORITHMS:
        try:
            return getattr(sb3, name).load(str(path), device="cpu")
        except Exception as e:  # noqa: BLE001 - each algorithm fails its own way on another's zip
            errors.append(f"{name}: {str(e).splitlines()[0] if str(e) else type(e).__name__}")
    raise PolicyError(f"policy: sb3: cannot load '{path}' ({'; '.join(errors)[:200]})")


class SB3Policy(RuleChoosingPolicy):
    """The greedy (deterministic) rule choice of an SB3 model; see the module docstring."""

    def __init__(self, model: Any, rules: tuple[str, ...] | None = None, name: str = "sb3") -> None:
        super().__init__()
        self.model = model
        self.name = name
        obs, act = model.observation_space, model.action_space
        if len(obs.shape) != 3:
            raise PolicyError(f"policy: sb3: observation shape {obs.shape} is not a belt image")
        self.obs_shape: tuple[int, int, int] = tuple(int(v) for v in obs.shape)  # type: ignore[assignment]
        self.image = float(np.max(obs.high)) > 1.0
        self.multi = hasattr(act, "nvec")
        self.n_actions = int(act.nvec[0]) if self.multi else int(act.n)
        self.given_rules = rules
        self.rules: tuple[str, ...] = ()
        self.camera: BeltCamera | None = None
        self.scale = 1

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        super().reset(robots, rng)
        n = len(robots)
        k = self.n_actions if self.multi else round(self.n_actions ** (1.0 / n))
        if not self.multi and k**n != self.n_actions:
            raise PolicyError(
                f"policy: sb3: the model has {self.n_actions} actions, not K**{n} for {n} robots"
            )
        if self.multi and len(self.model.action_space.nvec) != n:
            raise PolicyError("policy: sb3: the model was trained for another robot count")
        rules = self.given_rules or tuple(RULES)[:k]
        if len(rules) != k:
            raise PolicyError(f"policy: sb3: the model chooses among {k} rules; name them")
        self.rules = rules

    def attach(self, belt: Belt) -> None:
        """Called by the line with its belt: a camera with this line's geometry."""
        scenario = Scenario.model_validate(
            {
                "name": "sb3",
                "belt": {
                    "length": belt.length,
                    "width": belt.width,
                    "speed": belt.speed,
                    "grid": list(belt.grid),
                },
                "robots": {
                    "count": len(self.robots),
                    "workspaces": [list(r.workspace) for r in self.robots],
                    "arm_speed": max(r.arm_speed for r in self.robots),
                },
            }
        )
        camera = BeltCamera(scenario, self.obs_shape[0])
        camera.attach(belt)
        c, h, w = camera.shape
        self.scale = self.obs_shape[1] // h if self.image else 1
        if (c, h * self.scale, w * self.scale) != self.obs_shape:
            raise PolicyError(
                f"policy: sb3: this line gives observations of shape {camera.shape} "
                f"(x{self.scale}), the model was trained on {self.obs_shape}"
            )
        self.camera = camera

    def observe(self, decision: Decision) -> np.ndarray:
        """The observation the environment would give at this decision."""
        assert self.camera is not None, "SB3Policy needs the belt: the line calls attach(belt)"
        obs = self.camera.belt(decision.time, (decision.robot,))
        if self.image:
            s = self.scale
            obs = obs.repeat(s, axis=1).repeat(s, axis=2) * np.uint8(255)
        return obs

    def select_rule(self, decision: Decision) -> str:
        action, _ = self.model.predict(self.observe(decision), deterministic=True)
        a = np.asarray(action).reshape(-1)
        n, k = len(self.robots), len(self.rules)
        if self.multi:
            return self.rules[int(a[decision.robot])]
        joint = int(a[0])
        return self.rules[(joint // k ** (n - 1 - decision.robot)) % k]


def from_spec(arg: str) -> SB3Policy:
    """``sb3:MODEL.zip`` or ``sb3:MODEL.zip@RULE,RULE,...``."""
    path, _, names = arg.partition("@")
    if not path:
        raise PolicyError("policy: sb3 needs a model file, e.g. sb3:runs/ppo.zip")
    rules = None
    if names:
        try:
            rules = rule_names(names.split(","))
        except ValueError as e:
            raise PolicyError(f"policy: sb3: {e}") from None
    model = load_model(Path(path).expanduser())
    return SB3Policy(model, rules, name=f"sb3 ({Path(path).name})")
