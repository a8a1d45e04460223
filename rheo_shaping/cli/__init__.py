"""The ``rheo-shaping`` command line tool.

Each subcommand lives in its own module of this package and exposes
``add_parser(subparsers)`` (which registers the subcommand and sets
``func`` to a callable taking the parsed args and returning an exit code).
User mistakes raise :class:`UserError`, which is printed without a
traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["main", "build_parser", "UserError", "SUBCOMMANDS"]

#: Subcommand modules, in the order ``--help`` lists them.
SUBCOMMANDS = ("identify", "simulate", "reproduce", "cell", "record", "record-cell", "replay",
               "import-csv", "diagnose")


class UserError(Exception):
    """A mistake in the user's input: printed as ``error: <message>``, exit 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rheo-shaping",
        description="Robotic shaping of thin rheological sheets over a mould.",
    )
    from .. import __version__
    parser.add_argument("--version", action="version", version=f"rheo-shaping {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"rheo_shaping.cli.{name.replace('-', '_')}")
        except ModuleNotFoundError as exc:
            if exc.name == f"rheo_shaping.cli.{name.replace('-', '_')}":
                continue  # not built yet
            raise
        module.add_parser(sub)
    for name, sp in sub.choices.items():
        if not any("--quiet" in a.option_strings for a in sp._actions):
            sp.add_argument("--quiet", action="store_true", dest="quiet_all",
                            help="print nothing but errors (the exit code tells the result; "
                                 "--json still prints its object)")
    return parser


#: Errors besides ValueError and ArithmeticError that say the model cannot run a cell (the
#: sheet's Newton solve, ruckig's planning), reported as a user's error; anything else is a
#: bug and keeps its traceback.
MODEL_ERRORS = ("ConvergenceError", "RuckigError",
                "BrokenProcessPool")      # a worker that died running the model


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if getattr(args, "quiet_all", False) and not getattr(args, "json", False):
            import contextlib
            import os
            with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
                return int(args.func(args) or 0)
        code = int(args.func(args) or 0)
        sys.stdout.flush()                 # a closed pipe shows here, not at the exit
        return code
    except BrokenPipeError:
        # the reader went away (`rheo-shaping ... | head`): stop quietly, as `cat` does
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141                          # 128 + SIGPIPE, the shell's code for it
    except UserError as exc:
        print(f"rheo-shaping {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:          # noqa: BLE001 - only the model's refusals, below
        # the model refused or could not run a cell the schema admits (a value at the edge
        # of its range: a sheet 5e-324 m thick, a stiffness of 1e-300 N/m): a clear error,
        # not a traceback; any other exception is a bug and keeps its traceback
        if not (isinstance(exc, (ArithmeticError, ValueError))
                or type(exc).__name__ in MODEL_ERRORS):
            raise
        where = getattr(args, "params", None)
        what = " ".join(str(exc).split())          # one line (ruckig dumps its input)
        what = what if len(what) <= 300 else what[:297] + "..."
        print(f"rheo-shaping {args.command}: error: the model cannot run this cell"
              f"{f' (--params {where})' if where else ''}: {type(exc).__name__}: {what}. "
              f"Parameters at the edges of their ranges can make the sheet model ill-posed "
              f"(docs/model.md)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
