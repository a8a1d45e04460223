"""Helpers shared by the subcommands: loading the cell, guarding user files."""
from __future__ import annotations

import argparse
import contextlib
import os
from pathlib import Path
from typing import Iterator

from ..params.config import ConfigError, load_cell
from ..params.params import CellParams
from . import UserError


def add_params_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", metavar="FILE",
                        help="params YAML of the cell (ROS --params-file format); default: the "
                             "default cell")


def add_movement_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--movement", type=int, choices=(0, 1, 2, 3, 4),
                        help="paper movement (1 vertical, 2 horizontal, 3 inclined, 4 two-step; "
                             "0 the params file's waypoints); default: the params file's "
                             "movement.number")


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


def add_executor_arguments(parser: argparse.ArgumentParser) -> None:
    """``--jobs N`` and ``--executor SPEC`` (see :mod:`rheo_shaping.parallel`)."""
    from ..parallel import SPEC_HELP
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, metavar="N",
                        help="local worker processes (default: all cores, here %(default)s)")
    parser.add_argument("--executor", metavar="SPEC", default=None,
                        help=f"where the independent runs go: {SPEC_HELP}; default local")


@contextlib.contextmanager
def executor_from_args(args: argparse.Namespace) -> Iterator:
    """The executor of ``--executor``/``--jobs``; a bad spec is a :class:`UserError`."""
    from ..parallel import executor_from_spec
    if args.jobs < 1:
        raise UserError(f"--jobs {args.jobs}: expected at least 1")
    with contextlib.ExitStack() as stack:
        try:
            executor = stack.enter_context(executor_from_spec(args.executor, jobs=args.jobs))
        except ValueError as exc:
            raise UserError(str(exc)) from None
        yield executor


def executor_label(args: argparse.Namespace) -> str:
    """How the runs were spread, for a closing line."""
    if args.executor:
        return f"executor {args.executor}"
    return f"{args.jobs} worker process{'es' if args.jobs > 1 else ''}"
