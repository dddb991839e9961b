"""Scenario fields a calibration varies or fits: dotted paths, list elements, allowed ranges.

A path is what ``--set`` takes (``robots.arm_speed``), plus an index for one element of a
list field (``robots.bin_offset.1``). Fitted fields must be numbers; their bounds are checked
against the range the scenario model allows (``pick_time >= 0``, ``workspace_length > 0``).
Values are applied to a scenario's mapping and validated again, so every fitted line passes
the same checks as a file.
"""

from __future__ import annotations

import copy
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from pnp_twin.studies.plan import RESERVED, StudyError
from pnp_twin.twin.loader import ScenarioError, validate
from pnp_twin.twin.scenario import Scenario


@dataclass(frozen=True)
class FieldRef:
    """One resolved path: the field's keys, an element index if any, and its allowed range."""

    path: str
    keys: tuple[str, ...]
    index: int | None
    numeric: bool
    whole: bool = False
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    def allowed(self) -> str:
        """The allowed range in words, e.g. ``>= 0`` or ``> 0 and <= 64``."""
        parts = []
        if self.low > -math.inf:
            parts.append(f"{'>' if self.low_open else '>='} {self.low:g}")
        if self.high < math.inf:
            parts.append(f"{'<' if self.high_open else '<='} {self.high:g}")
        return " and ".join(parts) or "any number"

    def admits(self, value: float) -> bool:
        """Whether ``value`` lies in the allowed range."""
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return math.isfinite(value) and above and below


def _unwrap(annotation: Any) -> tuple[Any, list[Any]]:
    """The annotation without ``Optional`` and ``Annotated``, and the metadata found."""
    metadata: list[Any] = []
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return _unwrap(args[0])
    if origin is typing.Annotated:
        base, *extra = typing.get_args(annotation)
        for e in extra:
            metadata.extend(e.metadata if isinstance(e, FieldInfo) else [e])
        inner, more = _unwrap(base)
        return inner, metadata + more
    return annotation, metadata


def _is_number(t: Any) -> bool:
    return t in (int, float)


def _range(ref: dict[str, Any], metadata: list[Any]) -> None:
    for m in metadata:
        if isinstance(m, at.Gt):
            ref.update(low=float(m.gt), low_open=True)  # type: ignore[arg-type]
        elif isinstance(m, at.Ge):
            ref.update(low=float(m.ge), low_open=False)  # type: ignore[arg-type]
        elif isinstance(m, at.Lt):
            ref.update(high=float(m.lt), high_open=True)  # type: ignore[arg-type]
        elif isinstance(m, at.Le):
            ref.update(high=float(m.le), high_open=False)  # type: ignore[arg-type]


def resolve_path(path: str, option: str = "field") -> FieldRef:
    """The field ``path`` names, or a one-line StudyError saying what is allowed."""
    keys = path.strip().split(".")
    if keys[0] in RESERVED:
        raise StudyError(f"{option} '{path}': cannot be calibrated; {RESERVED[keys[0]]}")
    model: type[BaseModel] = Scenario
    for depth, key in enumerate(keys):
        fields = model.model_fields
        if key not in fields:
            prefix = ".".join(keys[:depth])
            allowed = ", ".join(f"{prefix + '.' if prefix else ''}{k}" for k in fields)
            raise StudyError(f"{option} '{path}': not a scenario field; allowed {allowed}")
        info = fields[key]
        base, metadata = _unwrap(info.annotation)
        metadata = list(info.metadata) + metadata
        rest = keys[depth + 1 :]
        if isinstance(base, type) and issubclass(base, BaseModel):
            if not rest:
                raise StudyError(f"{option} '{path}': is a section; name one of its fields")
            model = base
            continue
        return _leaf(path, tuple(keys[: depth + 1]), base, metadata, rest, option)
    raise StudyError(f"{option} '{path}': not a scenario field")  # pragma: no cover


def _leaf(
    path: str, keys: tuple[str, ...], base: Any, metadata: list[Any], rest: list[str], option: str
) -> FieldRef:
    ref: dict[str, Any] = {}
    if not rest:
        if _is_number(base):
            _range(ref, metadata)
        return FieldRef(path, keys, None, _is_number(base), base is int, **ref)
    origin = typing.get_origin(base)
    if len(rest) != 1 or origin is not tuple or not (rest[0].isascii() and rest[0].isdigit()):
        raise StudyError(
            f"{option} '{path}': '{'.'.join(keys)}' is a value; only one element of a list "
            f"field can be named, by its index (e.g. robots.bin_offset.1)"
        )
    args = [a for a in typing.get_args(base) if a is not Ellipsis]
    index = int(rest[0])
    fixed = Ellipsis not in typing.get_args(base)
    if fixed and index >= len(args):
        raise StudyError(
            f"{option} '{path}': index {index} is out of range; allowed 0..{len(args) - 1}"
        )
    element, more = _unwrap(args[min(index, len(args) - 1)])
    if _is_number(element):
        _range(ref, more)
    return FieldRef(path, keys, index, _is_number(element), element is int, **ref)


def current_value(scenario: Scenario, ref: FieldRef) -> Any:
    """The scenario's value of the field (or element) ``ref`` names."""
    node: Any = scenario
    for key in ref.keys:
        node = getattr(node, key)
    if ref.index is not None:
        if node is None or ref.index >= len(node):
            raise StudyError(f"{ref.path}: the scenario's list has no element {ref.index}")
        node = node[ref.index]
    return node


def set_in(data: dict[str, Any], ref: FieldRef, value: Any, fallback: Scenario) -> None:
    """Set ``ref`` to ``value`` in a raw scenario mapping, in place; a list element whose list
    the mapping lacks starts from ``fallback``'s list."""
    node = data
    for key in ref.keys[:-1]:
        child = node.get(key)
        if not isinstance(child, dict):
            child = node[key] = {}
        node = child
    last = ref.keys[-1]
    if ref.index is None:
        node[last] = value
        return
    items = node.get(last)
    if not isinstance(items, list | tuple):
        whole = fallback
        for key in ref.keys:
            whole = getattr(whole, key)
        items = list(whole) if whole is not None else []
    items = list(items)
    if ref.index >= len(items):
        raise StudyError(f"{ref.path}: the scenario's list has no element {ref.index}")
    items[ref.index] = value
    node[last] = items


def apply_values(scenario: Scenario, values: Mapping[FieldRef, Any]) -> Scenario:
    """A new scenario with each field set to its value, validated again (one-line errors)."""
    data = scenario.model_dump(mode="json")
    for ref, value in values.items():
        set_in(data, ref, value, scenario)
    try:
        return validate(data)
    except ScenarioError as e:
        where = ", ".join(
            f"{r.path}={v:g}" if _num(v) else f"{r.path}={v}" for r, v in values.items()
        )
        raise StudyError(f"cannot simulate ({where}): {e}") from None


def _num(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def raw_with_values(
    data: Mapping[str, Any], values: Mapping[FieldRef, Any], fallback: Scenario
) -> dict[str, Any]:
    """A deep copy of a raw scenario mapping (a file's) with the values set."""
    out = copy.deepcopy(dict(data))
    for ref, value in values.items():
        set_in(out, ref, value, fallback)
    return out


@dataclass(frozen=True)
class FitParam:
    """One fitted unknown: one or more numeric fields that share its value, and its bounds."""

    refs: tuple[FieldRef, ...]
    low: float
    high: float

    @property
    def name(self) -> str:
        """The paths as ``--fit`` names them, e.g. ``robots.pick_time,robots.place_time``."""
        return ",".join(r.path for r in self.refs)


def _bound(text: str, spec: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise StudyError(f"--fit {spec}: '{text}' is not a number; give PATH=LO:HI") from None
    if not math.isfinite(value):
        raise StudyError(f"--fit {spec}: '{text}' is not a finite number")
    return value


def parse_fit(spec: str) -> FitParam:
    """``robots.bin_offset.1=0.2:0.8`` (or ``a.b,c.d=LO:HI`` for fields sharing one value)."""
    paths, sep, bounds = spec.partition("=")
    lo_text, colon, hi_text = bounds.partition(":")
    if not sep or not colon or not paths.strip():
        raise StudyError(f"--fit {spec}: not of the form PATH=LO:HI (e.g. robots.pick_time=0:0.2)")
    low, high = _bound(lo_text.strip(), spec), _bound(hi_text.strip(), spec)
    if not low < high:
        raise StudyError(f"--fit {spec}: LO {low:g} must be below HI {high:g}")
    refs = []
    for path in paths.split(","):
        ref = resolve_path(path.strip(), "--fit")
        if not ref.numeric:
            raise StudyError(
                f"--fit {ref.path}: is not a numeric field; only numbers can be fitted"
            )
        if ref.whole:
            raise StudyError(
                f"--fit {ref.path}: is a whole number; calibrate fits continuous fields "
                f"(compare whole numbers with `pnp-twin sweep`)"
            )
        for value in (low, high):
            if not ref.admits(value):
                raise StudyError(
                    f"--fit {spec}: bound {value:g} is outside {ref.path}'s allowed range "
                    f"({ref.allowed()})"
                )
        refs.append(ref)
    return FitParam(tuple(refs), low, high)


def check_distinct(params: list[FitParam], varied: list[FieldRef]) -> None:
    """No field is fitted twice or both fitted and varied by the targets."""
    seen: dict[str, str] = {r.path: "the targets file" for r in varied}
    for p in params:
        for r in p.refs:
            if r.path in seen:
                raise StudyError(f"--fit {r.path}: already given by {seen[r.path]}")
            seen[r.path] = "another --fit"
