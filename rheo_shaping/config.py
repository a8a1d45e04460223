"""Params YAML files: the ROS 2 ``--params-file`` format, read without ROS.

A file looks like::

    /**:
      ros__parameters:
        material: {k1: 95.0, c2: 1300.0}
        movement: {number: 4}
    simulator:
      ros__parameters:
        real_time_factor: 20.0

The cell (material, sheet, cake, tool, movement, solver, effects) lives in the ``/**``
section that every node reads; node sections hold node settings.  Nested
keys flatten to dotted names exactly as rcl does.  A plain mapping of cell
sections (no ``ros__parameters``) is accepted too.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from .params import CellParams
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
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of sections at the top level, got {type(data).__name__}")
    return data


def node_parameters(data: dict, node: str | None, path: str | Path = "") -> dict[str, Any]:
    """Flat parameters that ``node`` gets from a params file (``/**`` then its own section)."""
    sections = []
    if any(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
        for key in ("/**", "**", node, f"/{node}" if node else None):
            if key is not None and key in data:
                sec = data[key]
                if not isinstance(sec, dict) or not isinstance(sec.get("ros__parameters"), dict):
                    raise ConfigError(f"{path}: section '{key}' needs a 'ros__parameters' mapping")
                sections.append(sec["ros__parameters"])
    else:
        sections.append(data)
    flat: dict[str, Any] = {}
    for sec in sections:
        flat.update(flatten(sec))
    return flat


CELL_SECTIONS = ("material", "sheet", "cake", "tool", "movement", "solver", "effects")


def cell_from_flat(flat: dict[str, Any], where: str = "") -> CellParams:
    """The cell's parameters out of a flat dict (other names are ignored)."""
    cell = {k: v for k, v in flat.items() if k.split(".", 1)[0] in CELL_SECTIONS}
    try:
        return from_flat(CellParams, cell, where=where)
    except ParameterError as exc:
        raise ConfigError(str(exc)) from None


def load_cell(path: str | Path | None = None, node: str | None = "simulator") -> CellParams:
    """The cell described by a params file (the default cell when ``path`` is None)."""
    if path is None:
        return CellParams()
    data = read_yaml(path)
    flat = node_parameters(data, node, path)
    unknown = sorted({k.split(".", 1)[0] for k in flat} - set(CELL_SECTIONS) - KNOWN_NODE_KEYS)
    if unknown and not any(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
        raise ConfigError(f"{path}: unknown section '{unknown[0]}': expected {', '.join(CELL_SECTIONS)}")
    return cell_from_flat(flat, str(path))


#: Top-level names of node parameters that may sit beside the cell's (the
#: nodes' settings of rheo_shaping.node_params and rclpy's own); load_cell
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
