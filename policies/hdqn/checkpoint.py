"""Checkpoints: safetensors weights plus JSON metadata, never pickled code.

A checkpoint folder holds

- ``model.safetensors``: the online Q-network (all that inference needs);
- ``train_state.safetensors``: the target network, the RMSprop state and torch's RNG state;
- ``replay.npz`` (optional): the replay buffer as plain arrays;
- ``meta.json``: what the weights mean (scenario, mode, network preset, rules, observation
  shape, agent config), package versions, step counters and the numpy RNG state.

Training writes checkpoints (:mod:`pnp_twin.learning.train_checkpoint`): every file to a
temporary name in the same folder, moved into place with ``os.replace``; ``meta.json`` goes
last, so a folder whose meta exists is complete. This module reads them for inference: tensors
with safetensors and JSON with ``json``; no code is ever unpickled.

Nothing is used before it is checked: ``meta.json`` is validated against :class:`Meta` (a
pydantic schema: known keys only, types, bounds, a valid scenario, known rules, consistent
shapes), and the weights against the network the metadata describes (every tensor present
with its shape, nothing extra, all values finite). A broken checkpoint is one
:class:`CheckpointError` line naming the file and the problem.
"""

from __future__ import annotations

import json
import logging
import math
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import torch
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from safetensors.torch import load_file

from pnp_twin.policies.hdqn import MODES
from pnp_twin.policies.hdqn.agent import AgentConfig, QAgent
from pnp_twin.policies.hdqn.features import size as feature_size
from pnp_twin.policies.hdqn.network import PRESETS
from pnp_twin.policies.registry import rule_names
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.inputs import MODEL_BYTES, SCENARIO_BYTES, check_user_file, read_user_text
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)
_WARNED: set[tuple[Any, ...]] = set()
A = TypeVar("A", bound=QAgent)

FORMAT = 1
MODEL = "model.safetensors"
STATE = "train_state.safetensors"
REPLAY = "replay.npz"
META = "meta.json"


class CheckpointError(UserError):
    """A missing, unreadable or invalid checkpoint; the message is one line."""


MAX_CELLS = 1 << 20  # observation cells (C x H x W); a real belt image has a few thousand
MAX_ACTIONS = 1 << 20  # joint actions (K**N); paper_baseline's single mode has 1,296


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=False)


class AgentMeta(_Strict):
    """:class:`~policies.hdqn.agent.AgentConfig` as recorded."""

    network: str
    lr: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    gamma: Annotated[float, Field(ge=0, le=1)]
    double: bool
    grad_clip: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    target_every: Annotated[int, Field(ge=1)]

    @field_validator("network")
    @classmethod
    def _preset(cls, v: str) -> str:
        if v not in PRESETS:
            raise ValueError(f"'{v}' is not a network preset; allowed {', '.join(PRESETS)}")
        return v


class Meta(_Strict):
    """The schema of ``meta.json`` (training writes more keys into ``train_args``)."""

    format: Literal[1]
    name: str = ""
    mode: Literal[MODES]  # type: ignore[valid-type]
    view: Literal["window", "belt", "none"] | None = None
    termination: Literal["t_continue", "t_all", "t_any"] | None = None
    targets: Literal["td", "rollout", "teacher"] | None = None
    features: str | None = None
    """The decision features after the one-hot (:mod:`policies.hdqn.features`), or None."""
    rules: list[str]
    n_robots: Annotated[int, Field(ge=1, le=64)]
    scenario: dict[str, Any]
    train_args: dict[str, Any] = Field(default_factory=dict)
    device: str = "cpu"
    counters: dict[str, float | int | None] = Field(default_factory=dict)
    rng: dict[str, Any] | None = None  # older checkpoints kept numpy's RNG state here
    obs_shape: Annotated[
        list[Annotated[int, Field(ge=0, le=4096)]], Field(min_length=3, max_length=3)
    ]
    n_actions: Annotated[int, Field(ge=1, le=MAX_ACTIONS)]
    n_extra: Annotated[int, Field(ge=0, le=256)]
    agent: AgentMeta
    updates: Annotated[int, Field(ge=0)] = 0
    optimizer_groups: list[dict[str, Any]] = Field(default_factory=list)
    versions: dict[str, str] = Field(default_factory=dict)

    @field_validator("rules")
    @classmethod
    def _rules(cls, v: list[str]) -> list[str]:
        return list(rule_names(v))

    @field_validator("scenario", mode="before")
    @classmethod
    def _scenario(cls, v: Any) -> Any:
        if not isinstance(v, dict):
            raise ValueError("must be a scenario mapping")
        data = {k: x for k, x in v.items() if k != "source_dir"}  # kept by older versions
        try:
            Scenario.model_validate(data)
        except ValidationError as e:
            first = e.errors()[0]
            where = ".".join(str(p) for p in first["loc"])
            raise ValueError(f"{where}: {first['msg']}") from None
        return data

    @model_validator(mode="after")
    def _consistent(self) -> Meta:
        c, h, w = self.obs_shape
        if self.view == "none" and (self.obs_shape != [0, 1, 1] or self.features is None):
            raise ValueError(
                f"obs_shape: {self.obs_shape} with view 'none' (no image); a student that "
                "sees only its features has obs_shape [0, 1, 1] and a feature set"
            )
        if self.view != "none" and min(self.obs_shape) < 1:
            raise ValueError(f"obs_shape: {self.obs_shape}: every size must be at least 1")
        if c > 3:
            raise ValueError(f"obs_shape: {c} channels; the belt image has 1 to 3")
        if c * h * w > MAX_CELLS:
            raise ValueError(f"obs_shape: {self.obs_shape} is absurd (over {MAX_CELLS} cells)")
        k = len(self.rules)
        want = k**self.n_robots if self.mode == "single" else k
        if self.n_actions != want:
            raise ValueError(
                f"n_actions: {self.n_actions} does not fit {k} rules and {self.n_robots} "
                f"robots in {self.mode} mode (expected {want})"
            )
        if self.features is not None:
            try:
                want_extra = feature_size(self.features, k, self.n_robots)
            except ValueError as e:
                raise ValueError(str(e)) from None
            if self.n_extra != want_extra:
                raise ValueError(
                    f"n_extra: {self.n_extra} does not match the features '{self.features}' "
                    f"of {k} rules and {self.n_robots} robots (expected {want_extra})"
                )
        elif self.n_extra not in (0, self.n_robots):
            raise ValueError(
                f"n_extra: {self.n_extra} does not match n_robots = {self.n_robots} (its network "
                f"takes extra inputs of {self.n_extra} robots; allowed 0 or {self.n_robots}); "
                "meta.json was changed or does not belong to these weights: restore it or retrain"
            )
        return self


def check_meta(data: Any, where: str) -> dict[str, Any]:
    """``data`` validated against :class:`Meta` (a plain dict), or one CheckpointError line."""
    if not isinstance(data, dict):
        raise CheckpointError(
            f"checkpoint: {where}: must be a JSON object, not {type(data).__name__}"
        )
    try:
        meta = Meta.model_validate(data)
    except ValidationError as e:
        first = e.errors()[0]
        loc = ".".join(str(p) for p in first["loc"]) or "meta"
        msg = first["msg"].removeprefix("Value error, ")
        if first["type"] == "extra_forbidden":
            msg = f"unknown key; allowed {', '.join(Meta.model_fields)}"
        elif first["type"] == "missing":
            msg = "missing"
        raise CheckpointError(f"checkpoint: {where}: {loc}: {msg}") from None
    out = dict(data)
    out["scenario"] = meta.scenario
    out["rules"] = meta.rules
    return out


def check_weights(
    tensors: dict[str, torch.Tensor], expected: dict[str, torch.Tensor], where: str
) -> None:
    """The saved tensors match the network's (names, shapes) and are finite."""
    missing = sorted(set(expected) - set(tensors))
    if missing:
        raise CheckpointError(f"checkpoint: {where}: tensor {missing[0]} is missing")
    extra = sorted(set(tensors) - set(expected))
    if extra:
        raise CheckpointError(f"checkpoint: {where}: unexpected tensor {extra[0]}")
    for name, want in expected.items():
        got = tensors[name]
        if tuple(got.shape) != tuple(want.shape):
            raise CheckpointError(
                f"checkpoint: {where}: tensor {name} has shape {tuple(got.shape)}, the network "
                f"in meta.json needs {tuple(want.shape)}"
            )
        if got.is_floating_point() and not bool(torch.isfinite(got).all()):
            raise CheckpointError(
                f"checkpoint: {where}: tensor {name} holds NaN or infinite values; "
                "the model is broken (retrain it)"
            )


def read_tensors(path: Path, device: str = "cpu") -> dict[str, torch.Tensor]:
    """The tensors of a safetensors file, or one CheckpointError line (missing, truncated)."""
    if not path.exists():
        raise CheckpointError(f"checkpoint: {path} is missing")
    check_user_file(path, "checkpoint", MODEL_BYTES, CheckpointError)
    try:
        return load_file(str(path), device=device)
    except Exception as e:  # safetensors raises its own error types for corrupt files
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise CheckpointError(
            f"checkpoint: {path} is not a readable safetensors file ({first})"
        ) from None


def flush_subnormals(tensors: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The tensors with every subnormal float set to zero (the same sign of zero).

    Training leaves many weights in the subnormal range (|w| < 1.2e-38 in float32): pruned
    by weight decay towards zero but never exactly zero. Their values change no decision
    (each is some 1e-38 of the layer's sum), but many CPUs take a slow micro-code path for
    every arithmetic operation on one (about 100 cycles), which made a student's decision 5
    to 10 times slower on some Intel CPUs. Checkpoints are flushed when written and when read.
    """
    out = {}
    for name, value in tensors.items():
        if value.is_floating_point():
            tiny = torch.finfo(value.dtype).tiny
            value = torch.where(value.abs() < tiny, torch.zeros_like(value), value)
        out[name] = value
    return out


def count_subnormals(tensors: dict[str, torch.Tensor]) -> int:
    """How many floats in ``tensors`` are subnormal (non-zero and below the dtype's tiny)."""
    n = 0
    for value in tensors.values():
        if value.is_floating_point():
            tiny = torch.finfo(value.dtype).tiny
            n += int(((value != 0) & (value.abs() < tiny)).sum())
    return n


def warn_if_other_line(meta: dict[str, Any], belt: Any, robots: list[Any], where: str) -> None:
    """Log one warning when the line differs from the scenario the model was trained on
    (belt geometry or speed, workspaces, arm speed): the policy may not transfer."""
    trained = meta.get("scenario", {})
    tb, tr = trained.get("belt", {}), trained.get("robots", {})
    diffs = []
    for key in ("length", "width", "speed"):
        if key in tb and not math.isclose(float(tb[key]), float(getattr(belt, key))):
            diffs.append(f"belt.{key} {getattr(belt, key):g} (trained {float(tb[key]):g})")
    if "arm_speed" in tr and robots:
        arm = max(r.arm_speed for r in robots)
        if not math.isclose(float(tr["arm_speed"]), arm):
            diffs.append(f"robots.arm_speed {arm:g} (trained {float(tr['arm_speed']):g})")
    seen = (where, trained.get("name"), tuple(diffs))
    if diffs and seen not in _WARNED:  # once per process, not once per run of a sweep
        _WARNED.add(seen)
        log.warning(
            "warning: %s was trained on scenario '%s'; this line differs: %s",
            where,
            trained.get("name", "?"),
            ", ".join(diffs),
        )


def shipped_models() -> list[str]:
    """Names of the models shipped with the package (usable without a path)."""
    root = resources.files("pnp_twin.models")
    return sorted(p.name for p in root.iterdir() if p.is_dir() and (p / META).is_file())


def _shipped(path: Path) -> Path | None:
    """The shipped model a relative path that does not exist names: ``NAME`` or
    ``models/NAME`` (as the README writes it from a checkout)."""
    parts = path.parts
    if path.is_absolute() or path.exists() or not parts or len(parts) > 2:
        return None
    if len(parts) == 2 and parts[0] != "models":
        return None
    candidate = resources.files("pnp_twin.models") / parts[-1]
    return Path(str(candidate)) if (candidate / META).is_file() else None


def resolve(folder: str | Path) -> Path:
    """The checkpoint folder itself, the single run folder inside a training output, or a
    shipped model named like a scenario (:func:`shipped_models`)."""
    path = Path(folder).expanduser()
    path = _shipped(path) or path
    if (path / META).is_file():
        return path
    if not path.is_dir():
        shipped = ", ".join(shipped_models())
        raise CheckpointError(
            f"checkpoint: '{folder}' is not a folder; give a checkpoint folder or a shipped "
            f"model ({shipped})"
        )
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
    text = read_user_text(path / META, "checkpoint", SCENARIO_BYTES, CheckpointError)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CheckpointError(f"checkpoint: cannot read {path / META}: {first}") from None
    if isinstance(data, dict) and data.get("format") != FORMAT:
        raise CheckpointError(
            f"checkpoint: {path / META}: format: {data.get('format')!r}, expected {FORMAT}"
        )
    return check_meta(data, str(path / META))


def load_into(
    cls: type[A], folder: str | Path, device: str | torch.device = "cpu", flush: bool = True
) -> tuple[A, dict[str, Any]]:
    """An agent of class ``cls`` (:class:`QAgent` or a subclass) built as the checkpoint's
    metadata describes, with its online network's weights, checked, subnormals flushed to
    zero (``flush``), and in eval mode."""
    path = resolve(folder)
    meta = read_meta(path)
    config = AgentConfig(**meta["agent"])
    shape = tuple(meta["obs_shape"])
    agent = cls(config, shape, meta["n_actions"], meta["n_extra"], device)  # type: ignore[arg-type]
    weights = read_tensors(path / MODEL, str(agent.device))
    expected = {f"q.{k}": v for k, v in agent.q.state_dict().items()}
    check_weights(weights, expected, str(path / MODEL))
    if flush:  # older checkpoints were written with subnormals (flush_subnormals)
        weights = flush_subnormals(weights)
    agent.q.load_state_dict({k[2:]: v for k, v in weights.items()})
    agent.q.eval()
    return agent, meta


def load_agent(
    folder: str | Path, device: str | torch.device = "cpu"
) -> tuple[QAgent, dict[str, Any]]:
    """The trained meta-controller of a checkpoint, for inference (resuming training is
    :func:`pnp_twin.learning.train_checkpoint.load_trainer`)."""
    return load_into(QAgent, folder, device)
