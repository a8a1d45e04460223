"""ROS 2 parameters declared from the project's schema (rheo_shaping.params.schema).

Every leaf field of a parameter dataclass (:class:`~rheo_shaping.params.cell.CellParams`
with dotted names such as ``material.k1``; a node's settings from
:mod:`rheo_shaping.params.node_params` with plain names) becomes a ROS parameter with

* a ``ParameterDescriptor`` whose description holds the field's description,
  unit and valid range, with a ``FloatingPointRange`` / ``IntegerRange`` where
  the range is bounded on both sides;
* its default from the dataclass, overridden by ``--params-file``, which ``-p``
  beats (:func:`command_line_parameters`: rcl's own merge lets a params file's
  node section win over ``-p`` once the file has more than one node section, so
  the ``-p name:=value`` of the command line are applied again on top);
* an on-set-parameters callback that refuses, at runtime
  (``set_parameters``), any value the schema refuses, and any combination the
  dataclasses' cross-field checks refuse, with the schema's message (it names
  the parameter, the value and the range); and every parameter that is not
  ``tunable`` in the schema (the cell, the thresholds, timeouts and limits): those are
  read-only once the node is configured, a change means a new cell (a restart, or
  cleanup and configure through the lifecycle, which checks it against the simulator's
  cell again);
* a start-up check (:meth:`SchemaParameters.__init__`) that refuses an invalid
  value from the params file with the same message, and an unknown name in a
  cell section (a typo must not fall back to a default silently).

Numbers (and lists of numbers) are declared with dynamic typing so that ``120``
and ``120.0`` are both accepted for a float, as the core's YAML loader does;
the schema then checks and converts them.  rclpy applies a descriptor's range
before the callback; its message (``Parameter X out of range Min: .., Max: ..,
value: ..``) names parameter, range and value too.
"""
from __future__ import annotations

import array
import math
import sys
from typing import Any, Callable, Iterable, Mapping

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..params.config import CELL_SECTIONS
from ..params.node_params import ROS_BUILTIN_PARAMETERS
from .rclpy_private import parameter_overrides
from ..params.schema import FieldInfo, ParameterError, from_flat, iter_fields, validate_value


#: The process's command line as rclpy.init got it (run_node sets it; else sys.argv).
_COMMAND_LINE: list[str] | None = None


def set_command_line(argv: list[str] | None) -> None:
    """Remember the arguments given to ``rclpy.init`` (None: sys.argv)."""
    global _COMMAND_LINE
    _COMMAND_LINE = None if argv is None else list(argv)


def command_line_parameters(argv: Iterable[str] | None = None) -> dict[str, Any]:
    """The ``-p NAME:=VALUE`` / ``--param NAME:=VALUE`` of the ``--ros-args`` blocks.

    Values are YAML, as rcl reads them (``20.0`` float, ``20`` int, ``false`` bool,
    ``[1, 2]`` list); later ones win.  Arguments outside ``--ros-args ... --`` are
    not ROS's and are skipped.
    """
    import yaml
    args = list(sys.argv if argv is None else argv)
    out: dict[str, Any] = {}
    in_ros = False
    i = 0
    while i < len(args):
        a = args[i]
        if a == "--ros-args":
            in_ros = True
        elif a == "--":
            in_ros = False
        elif in_ros and a in ("-p", "--param") and i + 1 < len(args):
            i += 1
            name, sep, text = args[i].partition(":=")
            if sep and name and ":" not in name:
                try:
                    out[name] = yaml.safe_load(text) if text.strip() else text
                except yaml.YAMLError:
                    out[name] = text     # rcl then refuses it with its own message
        i += 1
    return out


def describe(fi: FieldInfo) -> ParameterDescriptor:
    """The ROS descriptor of one schema field."""
    spec = fi.spec
    unit = f" [{spec.unit}]" if spec.unit else ""
    valid = spec.range_text() if (spec.choices or spec.lo is not None or spec.hi is not None
                                  or spec.length is not None or spec.min_length) else ""
    text = (f"{spec.description}{unit}" + (f"; valid: {valid}" if valid else "")
            + ("" if spec.tunable else "; read-only while the node runs"))
    desc = ParameterDescriptor(name=fi.name, description=text, additional_constraints=valid)
    if fi.kind in (float, int, tuple):
        desc.dynamic_typing = True          # 120 and 120.0 both accepted; the schema checks
    lo, hi = spec.lo, spec.hi
    if lo is None or hi is None:
        pass
    elif fi.kind is float and math.isfinite(lo) and math.isfinite(hi):
        desc.floating_point_range = [FloatingPointRange(from_value=float(lo),
                                                        to_value=float(hi), step=0.0)]
    elif fi.kind is int:
        desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
    return desc


def ros_default(fi: FieldInfo) -> Any:
    """The default as rclpy takes it (lists for tuples)."""
    return list(fi.default) if isinstance(fi.default, tuple) else fi.default


def plain_value(value: Any) -> Any:
    """A parameter value as a plain Python value (arrays become lists)."""
    if isinstance(value, (array.array, tuple)):
        return list(value)
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return value.tolist()
    return value


class SchemaParameters:
    """The ROS parameters of ``node`` for the parameter dataclasses in ``groups``.

    ``groups`` maps an attribute name to a dataclass type, e.g.
    ``{"cell": CellParams, "settings": SimulatorNodeParams}``; after
    construction ``self.values["cell"]`` is the validated dataclass, rebuilt
    after every accepted change (``on_change(names)`` is then called with the
    names that changed).  Raises :class:`ParameterError` when the start-up
    values are invalid.
    """

    def __init__(self, node: Node, groups: Mapping[str, type],
                 on_change: Callable[[set[str]], None] | None = None,
                 cli_args: Iterable[str] | None = None, locked: bool = True):
        """``locked``: parameters that are not ``tunable`` are refused at runtime."""
        self.node = node
        self.locked = locked
        self.groups = dict(groups)
        self.fields: dict[str, FieldInfo] = {}
        self.group_of: dict[str, str] = {}
        for group, cls in self.groups.items():
            for fi in iter_fields(cls):
                if fi.name in self.fields:
                    raise ValueError(f"parameter {fi.name!r} declared twice")
                self.fields[fi.name] = fi
                self.group_of[fi.name] = group
        self.on_change = on_change
        self.values: dict[str, Any] = {}
        self._apply_command_line(cli_args)
        self._check_overrides()
        node.add_on_set_parameters_callback(self._validate)
        try:
            node.declare_parameters("", [(fi.name, ros_default(fi), describe(fi))
                                         for fi in self.fields.values()])
        except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
            raise ParameterError(str(exc)) from None
        current = self._current()
        for group, cls in self.groups.items():
            self.values[group] = self._build(group, cls, current)
        node.add_post_set_parameters_callback(self._changed)

    # -- queries ----------------------------------------------------------------
    def __getitem__(self, group: str) -> Any:
        return self.values[group]

    def names(self, group: str) -> list[str]:
        return [n for n, g in self.group_of.items() if g == group]

    # -- internals --------------------------------------------------------------
    def _apply_command_line(self, cli_args: Iterable[str] | None) -> None:
        """``-p`` beats the params file (the process's arguments, then the node's own)."""
        given = command_line_parameters(_COMMAND_LINE)
        given.update(command_line_parameters(["--ros-args", *cli_args] if cli_args else []))
        overrides = parameter_overrides(self.node)
        for name, value in given.items():
            try:
                param = Parameter(name, value=value)
            except TypeError:
                continue                 # not a parameter type: rcl has refused it already
            overrides[name] = param
            if self.node.has_parameter(name) and name not in self.fields:
                # declared by rclpy before us (use_sim_time): set it again
                if self.node.get_parameter(name).value != value:
                    result = self.node.set_parameters([param])[0]
                    if not result.successful:
                        raise ParameterError(f"-p {name}:={value!r}: {result.reason}")

    def _check_overrides(self) -> None:
        """Refuse invalid or unknown start-up values with the schema's message."""
        overrides = parameter_overrides(self.node)
        flat: dict[str, Any] = {}
        for name, p in overrides.items():
            value = plain_value(p.value)
            if name in self.fields:
                fi = self.fields[name]
                validate_value(name, value, fi.kind, fi.spec)   # raises ParameterError
                flat[name] = value
            elif name.split(".", 1)[0] in CELL_SECTIONS:
                if "cell" in self.groups:
                    raise ParameterError(f"unknown parameter '{name}' for node "
                                         f"'{self.node.get_name()}'")
                # the cell of a params file's /**: not this node's (the lifecycle manager)
            elif name not in ROS_BUILTIN_PARAMETERS and not name.startswith("qos_overrides."):
                self.node.get_logger().warning(
                    f"parameter '{name}' is not a parameter of this node: ignored")
        defaults = {n: ros_default(fi) for n, fi in self.fields.items()}
        defaults.update(flat)
        for group, cls in self.groups.items():
            self._build(group, cls, defaults)

    def _current(self) -> dict[str, Any]:
        return {name: plain_value(self.node.get_parameter(name).value) for name in self.fields}

    def _build(self, group: str, cls: type, flat: Mapping[str, Any]) -> Any:
        mine = {n: v for n, v in flat.items() if self.group_of.get(n) == group}
        return from_flat(cls, mine)

    def _validate(self, params: Iterable[Parameter]) -> SetParametersResult:
        """on-set-parameters: the schema's range and the cross-field checks."""
        try:
            updated: dict[str, Any] = {}
            for p in params:
                if p.name not in self.fields:
                    continue
                fi = self.fields[p.name]
                if self.locked and self.values and not fi.spec.tunable:
                    raise ParameterError(
                        f"parameter '{p.name}' is read-only while {self.node.get_name()} runs "
                        f"(the cell's safety rests on it): a change means a new cell, a "
                        f"restart or cleanup and configure through the lifecycle")
                updated[p.name] = validate_value(p.name, plain_value(p.value), fi.kind, fi.spec)
            if updated and self.values:       # after start-up: check the whole set
                flat = self._current()
                flat.update(updated)
                for group in {self.group_of[n] for n in updated}:
                    self._build(group, self.groups[group], flat)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _changed(self, params: Iterable[Parameter]) -> None:
        names = {p.name for p in params if p.name in self.fields}
        if not names or not self.values:
            return
        current = self._current()
        for group in {self.group_of[n] for n in names}:
            self.values[group] = self._build(group, self.groups[group], current)
        if self.on_change is not None:
            self.on_change(names)
