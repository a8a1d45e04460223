"""Params YAML files: the ROS 2 ``--params-file`` format, read without ROS.

A file looks like::

    /**:
      ros__parameters:
        material: {k1: 95.0, c2: 1300.0}
        movement: {number: 4}
    /**/simulator:
      ros__parameters:
        real_time_factor: 20.0

One rule for a valid file, rcl's (what ``rclpy.init`` accepts), plus the
project's own:

* the top level maps node names (``/**``, ``/**/simulator``, ``planner``, or
  namespaces nested as mappings) to a mapping holding ``ros__parameters`` and
  nothing else; parameters sit under ``ros__parameters`` only;
* a list holds values of one type (all floats, all integers, all booleans or
  all strings): ``[0.03, 1]`` is refused, write ``[0.03, 1.0]``; no lists of
  lists or of mappings; one YAML document;
* the cell (material, sheet, cake, tool, movement, solver, effects) lives in
  the ``/**`` section, which every node and every ``rheo-shaping`` command
  read; a node section holds that node's settings (rheo_shaping/params/node_params.py)
  and refuses cell parameters, which only that node would use;
* values are checked against the schema (names, types, ranges), node
  settings in their node's section too.

Nested keys flatten to dotted names exactly as rcl does.  The nodes run
:func:`check_params_file` on their ``--params-file`` before ``rclpy.init``
(rheo_shaping/nodes/spin.py), so a node and ``rheo-shaping simulate`` refuse
the same files with the same message, naming file, key, value and what was
expected.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from .cell import CellParams
from .schema import ParameterError, from_flat, to_flat


class ConfigError(ValueError):
    """A params file that cannot be used: the message names the file and what is wrong."""


def flatten(tree: dict, prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def read_yaml(path: str | Path) -> dict:
    """Parse a YAML file; errors name the file, line and column."""
    import yaml
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot be read ({exc.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "?"
        raise ConfigError(f"{path}: {where}: {exc.problem}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from None
    except RecursionError:
        raise ConfigError(f"{path}: nested too deep to read (a params file nests node names "
                          f"and parameters a few levels)") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of node names (e.g. '/**') at the top "
                          f"level, got {_kind(data)}")
    return data


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    return {int: "an integer", float: "a float", str: "a string", list: "a list",
            dict: "a mapping", type(None): "nothing (null)"}.get(type(value),
                                                                 type(value).__name__)


def sections(data: dict, path: str | Path = "") -> dict[str, dict[str, Any]]:
    """``{node name: flat parameters}`` of a parsed params file, by rcl's rules.

    Node names nested as mappings are joined with ``/`` (``{cell2: {planner: ...}}``
    is ``cell2/planner``).  Raises :class:`ConfigError` for what rcl refuses.
    """
    out: dict[str, dict[str, Any]] = {}

    def walk(tree: dict, prefix: str) -> None:
        for key, value in tree.items():
            name = f"{prefix}/{key}" if prefix else str(key)
            if not isinstance(value, dict):
                where = f"section '{prefix}' has no 'ros__parameters': " if prefix else ""
                example = (f"{prefix.rsplit('/', 1)[-1]}: {{{key}: ...}}" if prefix
                           else f"{key}: ...")
                raise ConfigError(
                    f"{path}: {where}'{key}' = {value!r} sits where rcl expects a node "
                    f"section; expected parameters under '<node>: ros__parameters:', e.g. "
                    f"'/**: {{ros__parameters: {{{example}}}}}'")
            if "ros__parameters" in value:
                extra = [k for k in value if k != "ros__parameters"]
                if extra:
                    raise ConfigError(
                        f"{path}: section '{name}' has '{extra[0]}' beside 'ros__parameters': "
                        f"expected only 'ros__parameters' there")
                params = value["ros__parameters"]
                if params is None:
                    params = {}
                if not isinstance(params, dict):
                    raise ConfigError(f"{path}: '{name}.ros__parameters' = {params!r}: "
                                      f"expected a mapping of parameters")
                flat = flatten(params)
                for key2, v in flat.items():
                    _check_rcl_value(path, name, key2, v)
                out.setdefault(name, {}).update(flat)
            elif value:
                walk(value, name)
            else:
                raise ConfigError(f"{path}: section '{name}' is empty: expected "
                                  f"'ros__parameters' under it")

    walk(data, "")
    return out


def _check_rcl_value(path, section: str, key: str, value: Any) -> None:
    """rcl's rule for a parameter value: a scalar, or a list of scalars of one type."""
    if not isinstance(value, list):
        return
    where = f"{path}: '{section}' parameter '{key}' = {value!r}"
    kinds = []
    for v in value:
        if isinstance(v, (list, dict)):
            raise ConfigError(f"{where}: expected a list of numbers, booleans or strings, "
                              f"not of {_kind(v)}s")
        k = _kind(v)
        if k not in kinds:
            kinds.append(k)
    if len(kinds) > 1:
        hint = (" (write every number with a decimal point, e.g. 1.0)"
                if set(kinds) == {"a float", "an integer"} else "")
        raise ConfigError(f"{where}: expected the values of a list to be of one type, got "
                          f"{' and '.join(kinds)}{hint}")


#: Section names read by every node (and by the core): the cell lives here.
WILDCARD_SECTIONS = ("/**", "**")


def node_of(section: str) -> str | None:
    """The node a section is for (``/**/planner``, ``planner``, ``/cell2/planner``), or
    None for ``/**``."""
    if section in WILDCARD_SECTIONS:
        return None
    return section.rstrip("/").rsplit("/", 1)[-1]


def node_parameters(data: dict, node: str | None, path: str | Path = "") -> dict[str, Any]:
    """Flat parameters that ``node`` gets from a params file (``/**`` then its own section)."""
    flat: dict[str, Any] = {}
    found = sections(data, path)
    for name, params in found.items():
        if name in WILDCARD_SECTIONS:
            flat.update(params)
    if node is not None:
        for name, params in found.items():
            if node_of(name) == node:
                flat.update(params)
    return flat


def check_params_file(path: str | Path, data: Any = None) -> dict[str, dict[str, Any]]:
    """Refuse a params file that rcl or a node would refuse (module docstring); return its
    sections.  The message names the file, the section, the key, the value and what was
    expected.  ``data``: the file as :func:`read_yaml` read it (read here when None)."""
    from .node_params import NODE_PARAMS, NODE_PARAMETER_NAMES, ROS_BUILTIN_PARAMETERS
    if data is None:
        data = read_yaml(path)
    found = sections(data, path)
    for name, flat in found.items():
        node = node_of(name)
        cell_keys = sorted(k for k in flat if k.split(".", 1)[0] in CELL_SECTIONS)
        if node is None:
            cell_from_flat(flat, str(path))
            continue
        if cell_keys:
            k = cell_keys[0]
            raise ConfigError(
                f"{path}: section '{name}' sets cell parameter '{k}' = {flat[k]!r}: expected "
                f"the cell in the '/**' section, which every node and every rheo-shaping "
                f"command read (a cell parameter in one node's section would be used by that "
                f"node only)")
        cls = NODE_PARAMS.get(node)
        if cls is None:
            continue                    # another package's node: not ours to check
        mine = {k: v for k, v in flat.items() if k in NODE_PARAMETER_NAMES
                and k not in ROS_BUILTIN_PARAMETERS}
        own = {fi for fi in mine if fi in _field_names(cls)}
        try:
            from_flat(cls, {k: mine[k] for k in own}, where=f"{path}: section '{name}'")
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
    return found


def _field_names(cls: type) -> set[str]:
    from .schema import iter_fields
    return {fi.name for fi in iter_fields(cls)}


CELL_SECTIONS = ("material", "sheet", "cake", "tool", "movement", "solver", "effects")


def cell_from_flat(flat: dict[str, Any], where: str = "") -> CellParams:
    """The cell's parameters out of a flat dict (other names are ignored)."""
    cell = {k: v for k, v in flat.items() if k.split(".", 1)[0] in CELL_SECTIONS}
    try:
        return from_flat(CellParams, cell, where=where)
    except ParameterError as exc:
        msg = str(exc)
        if where and where not in msg:   # a check across parameters names no file itself
            msg = f"{msg} (in {where})"
        raise ConfigError(msg) from None


def load_cell(path: str | Path | None = None, node: str | None = "simulator") -> CellParams:
    """The cell described by a params file (the default cell when ``path`` is None)."""
    if path is None:
        return CellParams()
    data = read_yaml(path)                     # the file is read once
    check_params_file(path, data)
    return cell_from_flat(node_parameters(data, None, path), str(path))


#: Top-level names of node parameters that may sit beside the cell's (the
#: nodes' settings of rheo_shaping.params.node_params and rclpy's own); load_cell
#: ignores them, and the node sections (simulator, planner, monitor).
def _node_keys() -> set[str]:
    from .node_params import NODE_PARAMETER_NAMES, NODE_PARAMS, ROS_BUILTIN_PARAMETERS
    return set(NODE_PARAMETER_NAMES) | set(ROS_BUILTIN_PARAMETERS) | set(NODE_PARAMS)


KNOWN_NODE_KEYS: set[str] = _node_keys()


def dump_cell(params: CellParams) -> str:
    """The cell as a params YAML (``/**`` section)."""
    import yaml
    tree: dict = {}
    for name, value in to_flat(params).items():
        node = tree
        *parents, leaf = name.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return yaml.safe_dump({"/**": {"ros__parameters": tree}}, sort_keys=False)
