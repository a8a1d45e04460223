"""Helpers shared by the subcommands: loading the cell, guarding user files."""
from __future__ import annotations

import argparse
from pathlib import Path

from ..config import ConfigError, load_cell
from ..params import CellParams
from . import UserError


def add_params_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", metavar="FILE",
                        help="params YAML of the cell (ROS --params-file format); default: the default cell")


def cell_from_args(args: argparse.Namespace) -> CellParams:
    """The cell of ``--params`` (or the default), with user errors as :class:`UserError`."""
    try:
        return load_cell(args.params)
    except ConfigError as exc:
        raise UserError(str(exc)) from None


def output_path(path: str | None, force: bool, what: str = "file") -> Path | None:
    """A path to write, refusing to overwrite an existing file unless ``force``."""
    if path is None:
        return None
    p = Path(path)
    if p.exists() and not force:
        raise UserError(f"{what} {p} exists: not overwritten (use --force to replace it)")
    if not p.parent.exists():
        raise UserError(f"{what} {p}: folder {p.parent} does not exist")
    return p
