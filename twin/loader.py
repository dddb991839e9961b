"""Reading scenario files: TOML or YAML by suffix, shipped names, overrides, clean errors."""

from __future__ import annotations

import copy
import logging
import tomllib
from collections.abc import Iterable, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from twin.errors import UserError
from twin.scenario import Scenario

log = logging.getLogger(__name__)

SUFFIXES = (".toml", ".yaml", ".yml")


class ScenarioError(UserError):
    """A user mistake in a scenario or an override; its message is one line for the CLI."""


def shipped_scenarios() -> list[str]:
    """Names of the scenarios shipped with the package (usable without a path)."""
    root = resources.files("scenarios")
    return sorted(Path(p.name).stem for p in root.iterdir() if p.name.endswith(SUFFIXES))


def find_scenario(name_or_path: str | Path) -> Path:
    """The file for a path, or for the name of a shipped scenario."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    if path.suffix == "" and path.parent == Path("."):
        root = resources.files("scenarios")
        for suffix in SUFFIXES:
            candidate = root / f"{path.name}{suffix}"
            if candidate.is_file():
                return Path(str(candidate))
    shipped = ", ".join(shipped_scenarios())
    raise ScenarioError(
        f"scenario: no file '{name_or_path}'; give a path to a .toml/.yaml file "
        f"or a shipped name ({shipped})"
    )


def read_mapping(path: Path) -> dict[str, Any]:
    """The raw mapping of a TOML or YAML file."""
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ScenarioError(f"scenario: '{path}' has suffix '{suffix}'; allowed .toml, .yaml, .yml")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"scenario: cannot read '{path}': {e.strerror}") from None
    try:
        data = tomllib.loads(text) if suffix == ".toml" else yaml.safe_load(text)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"scenario: '{path}' is not valid TOML: {e}") from None
    except yaml.YAMLError as e:
        first = getattr(e, "problem", None) or (str(e).splitlines() or ["parse error"])[0]
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise ScenarioError(f"scenario: '{path}' is not valid YAML{where}: {first}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ScenarioError(f"scenario: '{path}' must hold a mapping of sections, not a list")
    return data


def parse_value(text: str) -> Any:
    """An override's value: a YAML scalar or list (numbers, true/false, [a, b], strings)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def parse_sets(items: Iterable[str]) -> dict[str, Any]:
    """``["robots.arm_speed=4", ...]`` -> ``{"robots.arm_speed": 4, ...}``."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"--set: '{item}' is not of the form path.to.field=value")
        out[key.strip()] = parse_value(value.strip())
    return out


def apply_overrides(data: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of ``data`` with each dotted path set to its value."""
    out = copy.deepcopy(dict(data))
    for dotted, value in overrides.items():
        keys = dotted.split(".")
        node: dict[str, Any] = out
        for depth, key in enumerate(keys[:-1]):
            child = node.get(key)
            if child is None:
                child = node[key] = {}
            if not isinstance(child, dict):
                where = ".".join(keys[: depth + 1])
                raise ScenarioError(f"--set {dotted}: '{where}' is a value, not a section")
            node = child
        node[keys[-1]] = value
    return out


def _format_error(e: ValidationError) -> str:
    err = e.errors()[0]
    loc = ".".join(str(p) for p in err["loc"] if not str(p).startswith("function-after"))
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] == "extra_forbidden":
        return f"{loc}: unknown key; check the spelling (see `pnp-twin schema`)"
    if err["type"] == "model_type" or not loc or msg.split(":", 1)[0].count(".") >= 1:
        return f"{loc + ': ' if loc and not msg.startswith(loc) else ''}{msg}"
    bad = err.get("input")
    return f"{loc}: {bad!r} is not allowed; {msg.lower()}"


def validate(data: Mapping[str, Any], source_dir: str | None = None) -> Scenario:
    """Validate a raw mapping into a Scenario, raising ScenarioError with one line."""
    payload = dict(data)
    if source_dir is not None:
        payload.setdefault("source_dir", source_dir)
    try:
        return Scenario.model_validate(payload)
    except ValidationError as e:
        raise ScenarioError(_format_error(e)) from None


def load_scenario(name_or_path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Load, override and validate a scenario file or shipped scenario name."""
    path = find_scenario(name_or_path)
    data = read_mapping(path)
    if overrides:
        data = apply_overrides(data, overrides)
    scenario = validate(data, source_dir=str(path.parent.resolve()))
    log.debug("loaded scenario %s from %s", scenario.name, path)
    return scenario


def with_overrides(scenario: Scenario, overrides: Mapping[str, Any]) -> Scenario:
    """A new scenario with dotted-path overrides applied and validated again."""
    data = scenario.model_dump(mode="json", exclude_none=False)
    return validate(apply_overrides(data, overrides))
