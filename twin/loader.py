"""Reading scenario files: TOML or YAML by suffix, shipped names, overrides, clean errors.

Every mistake is a :class:`ScenarioError` of one line naming the file or the field, an
excerpt of the bad value (never the whole input) and what is allowed. Files are read as
UTF-8 (at most :data:`MAX_BYTES`); YAML is read safely and without aliases (``*name``), so a
"billion laughs" file cannot expand; an empty file is refused, so a field left out means
"as in ``paper_baseline``" only when the user wrote something. A scenario that replays a
trace has its trace checked when it is loaded (:func:`twin.trace.check_replay`).
"""

from __future__ import annotations

import copy
import functools
import logging
import tomllib
import typing
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from pnp_twin.twin.errors import ScenarioError, clip, excerpt, read_user_text
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import check_replay

__all__ = [
    "ScenarioError",
    "apply_overrides",
    "find_scenario",
    "load_scenario",
    "parse_sets",
    "read_mapping",
    "shipped_scenarios",
    "validate",
    "with_overrides",
]

log = logging.getLogger(__name__)

SUFFIXES = (".toml", ".yaml", ".yml")
MAX_BYTES = 1_000_000  # a scenario is a page of settings; anything larger is a mistake
INTERNAL = {"source_dir": "set by the loader (the scenario file's folder), not by the user"}


@functools.cache
def safe_no_alias_loader() -> type:
    """PyYAML's safe loader, refusing aliases: a scenario never needs them, and a chain of
    them (the "billion laughs") expands a small file into gigabytes. (Built on first use, so
    TOML scenarios never import PyYAML.)"""
    import yaml

    class SafeNoAliasLoader(yaml.SafeLoader):
        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.AliasEvent):
                event = self.peek_event()
                raise yaml.composer.ComposerError(
                    None,
                    None,
                    "aliases (*name) are not allowed; write the value out",
                    event.start_mark,
                )
            return super().compose_node(parent, index)

    return SafeNoAliasLoader


def shipped_scenarios() -> list[str]:
    """Names of the scenarios shipped with the package (usable without a path)."""
    root = resources.files("pnp_twin.scenarios")
    return sorted(Path(p.name).stem for p in root.iterdir() if p.name.endswith(SUFFIXES))


def find_scenario(name_or_path: str | Path) -> Path:
    """The file for a path, or for the name of a shipped scenario."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    if path.suffix == "" and path.parent == Path("."):
        root = resources.files("pnp_twin.scenarios")
        for suffix in SUFFIXES:
            candidate = root / f"{path.name}{suffix}"
            if candidate.is_file():
                return Path(str(candidate))
    shipped = ", ".join(shipped_scenarios())
    raise ScenarioError(
        f"scenario: no file {excerpt(str(name_or_path))}; give a path to a .toml/.yaml file "
        f"or a shipped name ({shipped})"
    )


def _parse(text: str, path: Path, suffix: str) -> Any:
    if suffix == ".toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ScenarioError(
                f"scenario: '{path}' is not valid TOML: {clip(str(e), 120)}"
            ) from None
        except RecursionError:
            raise ScenarioError(
                f"scenario: '{path}' is nested too deeply to be a scenario"
            ) from None
    import yaml

    try:
        return yaml.load(text, Loader=safe_no_alias_loader())  # noqa: S506 (a safe loader)
    except yaml.YAMLError as e:
        first = getattr(e, "problem", None) or (str(e).splitlines() or ["parse error"])[0]
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise ScenarioError(
            f"scenario: '{path}' is not valid YAML{where}: {clip(str(first), 120)}"
        ) from None
    except RecursionError:
        raise ScenarioError(f"scenario: '{path}' is nested too deeply to be a scenario") from None


def read_mapping(path: Path) -> dict[str, Any]:
    """The raw mapping of a TOML or YAML file; an empty file is refused."""
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ScenarioError(f"scenario: '{path}' has suffix '{suffix}'; allowed .toml, .yaml, .yml")
    text = read_user_text(path, "scenario", MAX_BYTES, ScenarioError)
    data = _parse(text, path, suffix)
    if not isinstance(data, dict | type(None)):
        raise ScenarioError(f"scenario: '{path}' must hold a mapping of sections, not a list")
    if not data:
        raise ScenarioError(
            f"scenario: '{path}' is empty; give at least one setting (fields left out are "
            "as in paper_baseline), e.g. start from `pnp-twin validate paper_baseline`"
        )
    return data


def parse_value(text: str) -> Any:
    """An override's value: a number (``1e12``, ``nan`` are numbers, refused later if not
    allowed), or a YAML scalar or list (true/false, null, [a, b], strings)."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    import yaml

    try:
        value = yaml.load(text, Loader=safe_no_alias_loader())  # noqa: S506 (a safe loader)
    except (yaml.YAMLError, RecursionError):
        return text
    if isinstance(value, list):  # [nan, 1e3]: YAML reads these as text, we as numbers
        return [_number_or_text(v) for v in value]
    return value


def _number_or_text(value: Any) -> Any:
    if isinstance(value, list):
        return [_number_or_text(v) for v in value]
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


def parse_sets(items: Iterable[str]) -> dict[str, Any]:
    """``["robots.arm_speed=4", ...]`` -> ``{"robots.arm_speed": 4, ...}``."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"--set: {excerpt(item)} is not of the form path.to.field=value")
        key = key.strip()
        out[key] = value.strip() if key in TEXT_FIELDS else parse_value(value.strip())
    return out


# Fields that hold free text: their --set value is taken as written (``name=on`` is the text
# "on", ``description=Line 3: week 12`` is not a mapping, ``007`` keeps its zeros).
TEXT_FIELDS = frozenset({"name", "description", "policy", "feeder.trace"})


def apply_overrides(data: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of ``data`` with each dotted path set to its value."""
    out = copy.deepcopy(dict(data))
    for dotted, value in overrides.items():
        keys = dotted.split(".")
        if keys[0] in INTERNAL:
            raise ScenarioError(f"--set {keys[0]}: not a scenario field; {INTERNAL[keys[0]]}")
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


def _field(loc: Sequence[Any]) -> FieldInfo | None:
    """The pydantic field an error location points at (None when it is not a field)."""
    model: type[BaseModel] | None = Scenario
    info = None
    for key in loc:
        if isinstance(key, int):
            continue
        if model is None or key not in model.model_fields:
            return info if model is None else None
        info = model.model_fields[key]
        ann = info.annotation
        inner = [ann, *typing.get_args(ann)]
        model = next((a for a in inner if isinstance(a, type) and issubclass(a, BaseModel)), None)
    return info


def _unit(loc: Sequence[Any]) -> str:
    info = _field(loc)
    extra = info.json_schema_extra if info is not None else None
    unit = extra.get("unit") if isinstance(extra, dict) else None
    return f" {unit}" if isinstance(unit, str) and unit != "1" else ""


def _is_tag(part: Any) -> bool:
    """A location part pydantic adds for a validator or a union member, not a field name."""
    text = str(part)
    return "[" in text or "(" in text or text.startswith("function-") or text in TAGS


TAGS = {"constrained-int", "constrained-float", "constrained-str", "int", "float", "str"}


def _format_error(e: ValidationError) -> str:
    err = e.errors()[0]
    parts = [p for p in err["loc"] if not _is_tag(p)]
    loc = ".".join(str(p) for p in parts)
    msg = err["msg"].removeprefix("Value error, ").replace("a valid tuple", "a list")
    kind = err["type"]
    if kind == "extra_forbidden":
        if loc in INTERNAL:
            return f"{loc}: not a scenario field; {INTERNAL[loc]}"
        return f"{loc}: unknown key; check the spelling (see `pnp-twin schema`)"
    bad = excerpt(err.get("input"))
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"{loc}: {bad} is not allowed; {loc} is a section of fields (see `pnp-twin schema`)"
    if kind == "string_pattern_mismatch":
        return f"{loc}: {bad} is not allowed; give one line of text (no control characters)"
    if not loc or msg.split(":", 1)[0].count(".") >= 1:
        return f"{loc + ': ' if loc and not msg.startswith(loc) else ''}{msg}"
    unit = _unit(parts) if msg[-1:].isdigit() else ""
    return f"{loc}: {bad} is not allowed; {msg.lower()}{unit}"


def validate(data: Mapping[str, Any], source_dir: str | None = None) -> Scenario:
    """Validate a raw mapping into a Scenario (read from ``source_dir``), or one-line error."""
    try:
        return Scenario.model_validate(dict(data)).located(source_dir)
    except ValidationError as e:
        raise ScenarioError(_format_error(e)) from None


def load_scenario(name_or_path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Load, override and validate a scenario file or shipped scenario name.

    A trace the scenario replays is read and checked against its duration here, so a bad
    trace is a one-line error before anything runs.
    """
    path = find_scenario(name_or_path)
    data = read_mapping(path)
    if overrides:
        data = apply_overrides(data, overrides)
    scenario = validate(data, source_dir=str(path.parent.resolve()))
    check_replay(scenario)
    log.debug("loaded scenario %s from %s", scenario.name, path)
    return scenario


def with_overrides(scenario: Scenario, overrides: Mapping[str, Any]) -> Scenario:
    """A new scenario with dotted-path overrides applied and validated again."""
    data = scenario.model_dump(mode="json", exclude_none=False)
    return validate(apply_overrides(data, overrides), source_dir=scenario.source_dir)
