"""Reading scenario files: TOML or YAML by suffix, shipped names, overrides, clean errors.

Every mistake is a :class:`ScenarioError` of one line naming the file or the field, an
excerpt of the bad value (never the whole input) and what is allowed. Files are read as
UTF-8 (at most :data:`~pnp_twin.twin.inputs.SCENARIO_BYTES`); YAML is read safely and
without aliases (``*name``), so a "billion laughs" file cannot expand; an empty file is
refused, so a field left out means "as in ``paper_baseline``" only when the user wrote
something. A scenario that replays a trace has its trace checked when it is loaded
(:func:`twin.trace.check_replay`).
"""

from __future__ import annotations

import copy
import functools
import logging
import re
import tomllib
import typing
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from pnp_twin.twin.errors import ScenarioError, clip, excerpt
from pnp_twin.twin.inputs import SCENARIO_BYTES, check_regular, read_user_text
from pnp_twin.twin.scenario import Scenario
from pnp_twin.twin.trace import arrival_from_trace, check_replay

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


YAML11_BOOL = re.compile(r"^(?:yes|Yes|YES|no|No|NO|on|On|ON|off|Off|OFF)$")
YAML12_NUMBER = re.compile(
    r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|0o[0-7]+|0x[0-9a-fA-F]+"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
)


@dataclass(frozen=True)
class Ambiguous:
    """A plain YAML scalar that YAML 1.1 (PyYAML) and YAML 1.2 read differently (``yes``,
    ``NO``, ``1e3``, ``010``, ``1_000``, ``1:30``): kept aside, then refused with a hint."""

    text: str
    line: int
    yaml11: Any  # what PyYAML (YAML 1.1) reads
    yaml12: Any  # what a YAML 1.2 reader reads

    def hint(self) -> str:
        if isinstance(self.yaml11, bool):
            return (
                f"YAML 1.1 reads it as {self.yaml11}, YAML 1.2 as the text '{self.text}'; write "
                f"{str(self.yaml11).lower()} for a yes/no value, or quote it ('{self.text}') "
                "for text"
            )
        if isinstance(self.yaml11, str):
            return (
                f"YAML 1.1 reads it as text, YAML 1.2 as the number {self.yaml12!r}; write "
                f"{_yaml11_number(self.yaml12)} for a number, or quote it ('{self.text}') for "
                "text"
            )
        return (
            f"YAML 1.1 reads it as {self.yaml11!r}, YAML 1.2 as {self.yaml12!r}; write "
            f"{_yaml11_number(self.yaml11)} for the number, or quote it ('{self.text}') for text"
        )


def _yaml11_number(value: Any) -> str:
    """``value`` written so that YAML 1.1 and 1.2 read the same number (``1.0e+300``)."""
    if isinstance(value, int) or not isinstance(value, float):
        return str(value)
    text = repr(value)
    if "e" in text:
        mantissa, exponent = text.split("e")
        mantissa = mantissa if "." in mantissa else f"{mantissa}.0"
        sign = "" if exponent[0] in "+-" else "+"
        return f"{mantissa}e{sign}{exponent}"
    return text


def _yaml12_value(text: str) -> Any:
    """What a YAML 1.2 (core schema) reader makes of a plain scalar that looks numeric."""
    t = text.replace("_", "")
    for base, prefix in ((8, "0o"), (16, "0x")):
        if t.lower().startswith(prefix):
            try:
                return int(t[2:], base)
            except ValueError:
                return text
    try:
        return int(t) if re.fullmatch(r"[-+]?[0-9]+", t) else float(t)
    except ValueError:
        return text


@functools.cache
def strict_yaml_loader() -> type:
    """The loader of scenario files: :func:`safe_no_alias_loader` that also refuses a key
    given twice in a mapping, and keeps aside (as :class:`Ambiguous`) every plain scalar that
    YAML 1.1 and 1.2 read differently, so that it can be refused with its field's name."""
    import yaml

    class StrictLoader(safe_no_alias_loader()):  # type: ignore[misc]
        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            seen: dict[Any, int] = {}
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode):
                    key = key_node.value
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None,
                            None,
                            f"key '{clip(key, 40)}' is given twice (first on line {seen[key]}); "
                            "give each key once",
                            key_node.start_mark,
                        )
                    seen[key] = key_node.start_mark.line + 1
            return super().construct_mapping(node, deep=deep)

        def construct_object(self, node: Any, deep: bool = False) -> Any:
            value = super().construct_object(node, deep=deep)
            if isinstance(node, yaml.ScalarNode) and node.style is None:
                text = node.value
                line = node.start_mark.line + 1
                if isinstance(value, bool) and YAML11_BOOL.match(text):
                    return Ambiguous(text, line, value, text)
                if isinstance(value, int | float) and not isinstance(value, bool):
                    t = text.lstrip("+-")
                    octal = len(t) > 1 and t[0] == "0" and t[1:2].isdigit()
                    if "_" in t or ":" in t or t[:2].lower() == "0b" or octal:
                        return Ambiguous(text, line, value, _yaml12_value(text))
                if isinstance(value, str) and YAML12_NUMBER.match(text):
                    return Ambiguous(text, line, value, _yaml12_value(text))
            return value

    return StrictLoader


def _first_ambiguous(data: Any, path: str = "") -> tuple[str, Ambiguous] | None:
    """The first :class:`Ambiguous` scalar in ``data``, with its dotted path."""
    if isinstance(data, Ambiguous):
        return path, data
    if isinstance(data, dict):
        for key, value in data.items():
            if isinstance(key, Ambiguous):
                return (f"{path}." if path else "") + "(a key)", key
            found = _first_ambiguous(value, f"{path}.{key}" if path else str(key))
            if found:
                return found
    if isinstance(data, list):
        for i, value in enumerate(data):
            found = _first_ambiguous(value, f"{path}.{i}")
            if found:
                return found
    return None


def shipped_scenarios() -> list[str]:
    """Names of the scenarios shipped with the package (usable without a path)."""
    root = resources.files("pnp_twin.scenarios")
    return sorted(Path(p.name).stem for p in root.iterdir() if p.name.endswith(SUFFIXES))


def find_scenario(name_or_path: str | Path) -> Path:
    """The file for a path, or for the name of a shipped scenario."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    check_regular(path, "scenario", ScenarioError)  # a FIFO, a device, a folder: by its kind
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
        data = yaml.load(text, Loader=strict_yaml_loader())  # noqa: S506 (a safe loader)
    except yaml.YAMLError as e:
        first = getattr(e, "problem", None) or (str(e).splitlines() or ["parse error"])[0]
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise ScenarioError(
            f"scenario: '{path}' is not valid YAML{where}: {clip(str(first), 120)}"
        ) from None
    except RecursionError:
        raise ScenarioError(f"scenario: '{path}' is nested too deeply to be a scenario") from None
    found = _first_ambiguous(data)
    if found:
        where, scalar = found
        raise ScenarioError(
            f"{where}: {clip(scalar.text, 30)} on line {scalar.line} of '{path}' is ambiguous "
            f"in YAML: {scalar.hint()}"
        )
    return data


def read_mapping(path: Path) -> dict[str, Any]:
    """The raw mapping of a TOML or YAML file; an empty file is refused."""
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ScenarioError(f"scenario: '{path}' has suffix '{suffix}'; allowed .toml, .yaml, .yml")
    text = read_user_text(path, "scenario", SCENARIO_BYTES, ScenarioError)
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
            where = ".".join(keys[: depth + 1])
            index = keys[depth + 1]
            if index.isascii() and index.isdigit():  # one element of a list: robots.bin_offset.1
                if child is None:
                    child = _default(keys[: depth + 1])
                if isinstance(child, list | tuple):
                    if depth + 2 != len(keys):
                        raise ScenarioError(
                            f"--set {dotted}: only one element of a list field can be named, "
                            f"by its index (e.g. robots.bin_offset.1)"
                        )
                    node[key] = _with_element(dotted, where, child, int(keys[-1]), value)
                    break
                if child is None:
                    raise ScenarioError(
                        f"--set {dotted}: '{where}' is not set, so it has no element "
                        f"{keys[depth + 1]}; set the whole list (--set '{where}=[...]')"
                    )
            if child is None:
                child = node[key] = {}
            if not isinstance(child, dict):
                raise ScenarioError(f"--set {dotted}: '{where}' is a value, not a section")
            node = child
        else:
            node[keys[-1]] = value
    return out


@functools.cache
def _defaults() -> dict[str, Any]:
    return Scenario().model_dump(mode="json")


def _default(keys: Sequence[str]) -> Any:
    """The default (``paper_baseline``'s) value at a path, None when there is none."""
    node: Any = _defaults()
    for key in keys:
        node = node.get(key) if isinstance(node, dict) else None
    return copy.deepcopy(node)


def _with_element(dotted: str, where: str, items: Any, index: int, value: Any) -> list[Any]:
    out = list(items)
    if index >= len(out):
        allowed = f"0..{len(out) - 1}" if out else "none (the list is empty)"
        raise ScenarioError(
            f"--set {dotted}: index {index} is out of range; {where} has {len(out)} "
            f"elements, allowed {allowed}"
        )
    out[index] = value
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
    shape = _shape(parts)
    if shape and (
        kind in ("too_long", "too_short", "tuple_type", "list_type")
        or (kind == "missing" and parts and isinstance(parts[-1], int))
    ):
        if kind == "missing":  # pydantic points at the missing element; name the list
            parts = parts[:-1]
            loc = ".".join(str(p) for p in parts)
        return f"{loc}: {bad} is not allowed; give {shape}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"{loc}: {bad} is not allowed; {loc} is a section of fields (see `pnp-twin schema`)"
    if kind == "string_pattern_mismatch":
        return f"{loc}: {bad} is not allowed; give one line of text (no control characters)"
    if not loc or msg.split(":", 1)[0].count(".") >= 1 or "physical lower bound" in msg:
        return f"{loc + ': ' if loc and not msg.startswith(loc) else ''}{msg}"
    unit = _unit(parts) if msg[-1:].isdigit() else ""
    return f"{loc}: {bad} is not allowed; {msg.lower()}{unit}"


SHAPES = {
    "bin_offset": "two numbers [dx, dy] in m (along the belt from the workspace centre, "
    "beyond the upper belt edge)",
    "grid": "two whole numbers [cells along, cells across]",
    "workspaces": "one [a, b] pair of numbers in m per robot, e.g. [[0.3, 0.5], [0.5, 0.7]]",
}


def _shape(parts: Sequence[Any]) -> str | None:
    """What a list-shaped field needs, when the error is about that field's shape."""
    names = [p for p in parts if not isinstance(p, int)]
    if not names or names[-1] not in SHAPES:
        return None
    if names[-1] == "workspaces" and parts and isinstance(parts[-1], int):
        if len(parts) >= 2 and isinstance(parts[-2], int):  # an element of one workspace
            return "each workspace as two numbers [a, b] in m"
    return SHAPES[names[-1]]


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
        data, said = arrival_from_trace(data, overrides, path.parent.resolve())
        if said:
            log.warning("%s", said)  # one line on stderr: the trace is no longer replayed
        data = apply_overrides(data, overrides)
    scenario = validate(data, source_dir=str(path.parent.resolve()))
    check_replay(scenario)
    log.debug("loaded scenario %s from %s", scenario.name, path)
    return scenario


def with_overrides(scenario: Scenario, overrides: Mapping[str, Any]) -> Scenario:
    """A new scenario with dotted-path overrides applied and validated again (another
    ``feeder.arrival`` on a trace scenario takes the trace's mean rate, as ``--set`` does)."""
    data = scenario.model_dump(mode="json", exclude_none=False)
    data, said = arrival_from_trace(data, overrides, scenario.source_dir)
    if said:
        log.info("%s", said)
    return validate(apply_overrides(data, overrides), source_dir=scenario.source_dir)
