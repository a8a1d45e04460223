"""Declarative parameter fields: unit, description and valid range.

One schema serves the pure-Python core and the ROS 2 nodes: every parameter
set is a frozen dataclass whose fields are made with :func:`param`; the core
validates with :func:`validate_value`, the nodes turn the same metadata into
ROS ``ParameterDescriptor`` s (see ``rheo_shaping/nodes/ros_params.py``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Iterator, Sequence


@dataclass(frozen=True)
class Spec:
    """What a parameter means and which values it accepts."""

    description: str
    unit: str = ""
    lo: float | None = None          # lower bound (inclusive unless lo_open)
    hi: float | None = None          # upper bound (inclusive)
    lo_open: bool = False            # True: value must be > lo
    choices: tuple[str, ...] = ()    # for strings, and for each name of a list of names
    length: int | None = None        # for float arrays of fixed length
    min_length: int = 0              # for float arrays of variable length
    tunable: bool = False            # may change while a node runs (else read-only then)

    def range_text(self) -> str:
        """Human text of the valid range, e.g. ``(0, 1e+06] N/m``."""
        if self.choices:
            one = "one of " + ", ".join(repr(c) for c in self.choices)
            return (f"a list of at least {self.min_length} different names, each {one}"
                    if self.min_length else one)
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        text = f"{'(' if self.lo_open else '['}{lo}, {hi}]"
        if self.length is not None:
            text = f"{self.length} values each in {text}"
        elif self.min_length:
            text = f"at least {self.min_length} values each in {text}"
        return f"{text} {self.unit}".rstrip()


def param(default: Any, description: str, unit: str = "", lo: float | None = None,
          hi: float | None = None, lo_open: bool = False, choices: Sequence[str] = (),
          length: int | None = None, min_length: int = 0, tunable: bool = False) -> Any:
    """A dataclass field carrying a :class:`Spec` in its metadata.  ``tunable``: the value
    may change while a node runs (what it shows or how often); every other parameter is
    read-only once a node is configured (a change means a new cell)."""
    spec = Spec(description, unit, lo, hi, lo_open, tuple(choices), length, min_length,
                tunable)
    if isinstance(default, list):
        default = tuple(default)
    return field(default=default, metadata={"spec": spec})


class ParameterError(ValueError):
    """A parameter value is missing, of the wrong type or out of range."""


def _type_name(kind: type) -> str:
    return {float: "a number", int: "an integer", bool: "true or false",
            str: "a string", tuple: "a list of numbers"}[kind]


def validate_value(name: str, value: Any, kind: type, spec: Spec) -> Any:
    """Check one value against its type and spec; return it coerced.

    Raises :class:`ParameterError` naming the parameter, the value and the
    expected range.  Nothing is clamped.
    """
    def fail(expected: str) -> ParameterError:
        return ParameterError(f"parameter '{name}' = {value!r} is invalid: expected {expected}")

    if kind is bool:
        if not isinstance(value, bool):
            raise fail(_type_name(bool))
        return value
    if kind is str:
        if not isinstance(value, str):
            raise fail(_type_name(str))
        if spec.choices and value not in spec.choices:
            raise fail(spec.range_text())
        return value
    if kind is tuple and spec.choices:                   # a list of names
        if (not isinstance(value, (list, tuple)) or len(value) < spec.min_length
                or any(v not in spec.choices for v in value) or len(set(value)) < len(value)):
            raise fail(spec.range_text())
        return tuple(value)
    if kind is tuple:
        if not isinstance(value, (list, tuple)) or isinstance(value, str):
            raise fail(f"a list of numbers, {spec.range_text()}")
        items = tuple(value)
        if spec.length is not None and len(items) != spec.length:
            raise fail(spec.range_text())
        if len(items) < spec.min_length:
            raise fail(spec.range_text())
        out = []
        for item in items:
            if isinstance(item, bool) or not isinstance(item, (int, float)):
                raise fail(spec.range_text())
            if not _in_range(float(item), spec):
                raise fail(spec.range_text())
            out.append(float(item))
        return tuple(out)
    # numbers
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise fail(f"{_type_name(kind)} in {spec.range_text()}")
    if kind is int:
        if isinstance(value, float):
            if not value.is_integer():
                raise fail(f"an integer in {spec.range_text()}")
            value = int(value)
    else:
        value = float(value)
    if not _in_range(float(value), spec):
        raise fail(f"a value in {spec.range_text()}")
    return value


def _in_range(v: float, spec: Spec) -> bool:
    if math.isnan(v):
        return False
    if spec.lo is not None and (v < spec.lo or (spec.lo_open and v == spec.lo)):
        return False
    if spec.hi is not None and v > spec.hi:
        return False
    if math.isinf(v) and not (spec.hi is None and v > 0 or spec.lo is None and v < 0):
        return False
    return True


@dataclass(frozen=True)
class FieldInfo:
    """One leaf parameter: dotted name, Python type, default and spec."""

    name: str
    kind: type
    default: Any
    spec: Spec


def _kind_of(default: Any) -> type:
    for kind in (bool, int, float, str, tuple):
        if isinstance(default, kind):
            return kind
    raise TypeError(f"unsupported parameter default {default!r}")


def iter_fields(cls_or_obj: Any, prefix: str = "") -> Iterator[FieldInfo]:
    """All leaf parameters of a (nested) parameter dataclass, dotted names."""
    cls = cls_or_obj if isinstance(cls_or_obj, type) else type(cls_or_obj)
    for f in dataclasses.fields(cls):
        name = f"{prefix}{f.name}"
        if "spec" in f.metadata:
            yield FieldInfo(name, _kind_of(f.default), f.default, f.metadata["spec"])
        else:
            yield from iter_fields(_group_class(f), name + ".")


def _group_class(f: dataclasses.Field) -> type:
    """The dataclass of a nested parameter group, from its default factory (every group
    field is ``field(default_factory=GroupParams)``; a factory that is not a class is
    called for its instance's type)."""
    factory = f.default_factory
    if factory is dataclasses.MISSING:
        raise TypeError(f"parameter group '{f.name}' has no default_factory")
    if isinstance(factory, type):
        return factory
    return type(factory())


def from_flat(cls: type, values: dict[str, Any], prefix: str = "", *,
              where: str = "") -> Any:
    """Build a (nested) parameter dataclass from ``{"a.b": value}``.

    Missing names take their defaults; unknown names are an error (a typo
    must not silently fall back to a default).  ``where`` (e.g. a file name)
    is added to error messages.
    """
    known = {fi.name for fi in iter_fields(cls, prefix)}
    unknown = sorted(k for k in values if k.startswith(prefix) and k not in known)
    if unknown:
        loc = f" in {where}" if where else ""
        raise ParameterError(f"unknown parameter '{unknown[0]}'{loc}")
    return _build(cls, values, prefix, where)


def _build(cls: type, values: dict[str, Any], prefix: str, where: str) -> Any:
    kwargs = {}
    for f in dataclasses.fields(cls):
        name = f"{prefix}{f.name}"
        if "spec" in f.metadata:
            if name in values:
                try:
                    kwargs[f.name] = validate_value(name, values[name], _kind_of(f.default),
                                                    f.metadata["spec"])
                except ParameterError as exc:
                    raise ParameterError(f"{exc}{f' (in {where})' if where else ''}") from None
        else:
            kwargs[f.name] = _build(_group_class(f), values, name + ".", where)
    try:
        return cls(**kwargs)
    except ParameterError:
        raise
    except ValueError as exc:  # cross-field checks in __post_init__
        raise ParameterError(f"{exc}{f' (in {where})' if where else ''}") from None


def to_flat(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Inverse of :func:`from_flat`: ``{"a.b": value}`` for every leaf."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        name = f"{prefix}{f.name}"
        if "spec" in f.metadata:
            out[name] = list(value) if isinstance(value, tuple) else value
        else:
            out.update(to_flat(value, name + "."))
    return out
