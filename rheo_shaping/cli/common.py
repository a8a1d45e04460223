"""Helpers shared by the subcommands: loading the cell, guarding user files."""
from __future__ import annotations

import argparse
import contextlib
import os
from pathlib import Path
from typing import Iterator, overload

from ..params.config import ConfigError, load_cell
from ..params.cell import CellParams
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


@overload
def output_path(path: str, force: bool, what: str = ...) -> Path: ...


@overload
def output_path(path: None, force: bool, what: str = ...) -> None: ...


def output_path(path: str | None, force: bool, what: str = "file") -> Path | None:
    """A path to write, refusing to overwrite an existing file unless ``force``."""
    if path is None:
        return None
    p = Path(path)
    if p.is_dir():
        raise UserError(f"{what} {p}: is a folder; expected a file name")
    if p.exists() and not force:
        raise UserError(f"{what} {p} exists: not overwritten (use --force to replace it)")
    above = _first_existing(p)
    if not above.is_dir():
        raise UserError(f"{what} {p}: {above} is a file, not a folder; expected a file name "
                        "in an existing folder")
    if not p.parent.exists():
        raise UserError(f"{what} {p}: folder {p.parent} does not exist")
    _probe_writable(what, p, p.parent, "a file")
    return p


def _first_existing(p: Path) -> Path:
    """``p``'s nearest ancestor that exists (``.`` for a relative path at the top)."""
    a = p.parent
    while not a.exists() and a != a.parent:
        a = a.parent
    return a


def _probe_writable(option: str, p: Path, folder: Path, expected: str) -> None:
    """Create and remove a file in ``folder``: the one test that also holds for root, a
    read-only file system and an ACL (``os.access`` answers yes to root everywhere)."""
    import tempfile
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".rheo-shaping-probe-")
    except OSError as exc:
        raise UserError(f"{option} {p}: cannot write in folder {folder} "
                        f"({exc.strerror or exc}); expected {expected} in a writable "
                        "folder") from None
    os.close(fd)
    os.unlink(probe)


@overload
def output_dir(path: str, force: bool, option: str = ..., *, record: bool = ...,
               create: bool = ...) -> Path: ...


@overload
def output_dir(path: None, force: bool, option: str = ..., *, record: bool = ...,
               create: bool = ...) -> None: ...


def output_dir(path: str | None, force: bool, option: str = "--out", *,
               record: bool = False, create: bool = False) -> Path | None:
    """The folder an ``--out DIR`` option names, checked before any work is done: not an
    existing file, under an existing folder (not under a file), writable, and not holding
    anything that ``force`` was not given to replace.

    ``record``: the folder is a record directory, created by its writer: any existing path
    needs ``force`` (the writer replaces only a record). Otherwise an existing folder may
    be written into when empty or with ``force``; ``create`` makes a missing one.
    Each refusal is a one-line :class:`UserError` naming ``option``, the path and what was
    expected.
    """
    if path is None:
        return None
    p = Path(path)
    expected = "a new record folder" if record else "a folder (new, empty or with --force)"
    if p.exists() and not p.is_dir():
        raise UserError(f"{option} {p}: is an existing file, not a folder; expected {expected}")
    if p.is_dir():
        if record and not force:
            raise UserError(f"{option} {p}: exists: not overwritten (use --force to replace "
                            "the record)")
        if record:
            from ..records.bag import is_record_dir
            if not is_record_dir(p):
                raise UserError(f"{option} {p}: folder exists and is not a record (no "
                                "metadata.yaml and scenario.yaml): not replaced; expected "
                                f"{expected} or an old record")
        if not record and not force and any(p.iterdir()):
            raise UserError(f"{option} {p}: folder exists and is not empty: not written into "
                            "(use --force)")
        _probe_writable(option, p, p, expected)
        return p
    above = _first_existing(p)
    if not above.is_dir():
        raise UserError(f"{option} {p}: {above} is a file, not a folder; expected {expected} "
                        "inside an existing folder")
    if above != p.parent:
        raise UserError(f"{option} {p}: folder {p.parent} does not exist; expected {expected} "
                        "inside an existing folder")
    _probe_writable(option, p, above, expected)
    if create:
        try:
            p.mkdir()
        except OSError as exc:
            raise UserError(f"{option} {p}: cannot create the folder ({exc.strerror or exc}); "
                            f"expected {expected}") from None
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


def ros_namespace(text: str) -> str:
    """A ROS namespace from --namespace, or UserError naming what is wrong."""
    import re
    ns = text.strip()
    if ns in ("", "/"):
        return ""
    if not re.fullmatch(r"/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*", ns):
        raise UserError(f"--namespace = {text!r}: expected a ROS namespace such as /cell2 "
                        "(tokens of letters, digits and _, each starting with a letter)")
    return "/" + ns.lstrip("/")
