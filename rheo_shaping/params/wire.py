"""The cell's JSON messages read without a way to break the reader (docs/ros.md, "Who may
write what").

Every internal message of the cell that is JSON in a ``std_msgs/String`` (``/shaping/cell``,
``/shaping/presence``, a managed node's ``~/heartbeat``) and every params file is read
through :func:`load_json` (or checked by :func:`check_depth` before YAML reads it): bounded
length and nesting depth before any parser runs (100,000 ``[`` made ``json.loads`` raise
``RecursionError`` in every node), finite numbers only (``Infinity``, ``NaN`` and ``1e400``
are refused: an infinite ``transitions`` crashed the lifecycle manager on ``int()``), and,
with :func:`read_fields`, exactly the keys expected with their types and ranges.  What is
refused raises :class:`WireError` with the reason; a node drops the message and reports it
once.  No ROS imports here.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Mapping

#: Longest message text read [characters] (the cell's own: a cell message is ~2,500).
MAX_CHARS = 65_536
#: Deepest nesting of lists and objects read (the cell's own messages nest 2 deep).
MAX_DEPTH = 8


class WireError(ValueError):
    """A message (or params file) refused, with the reason."""


def check_depth(text: str, max_depth: int, what: str = "the message") -> None:
    """Raise :class:`WireError` when ``text`` nests brackets (``[``, ``{``, outside JSON
    strings) deeper than ``max_depth``; YAML flow and JSON alike.  Linear in the length."""
    depth = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > max_depth:
                raise WireError(f"{what} nests deeper than {max_depth} levels")
        elif ch in "]}":
            depth -= 1


def _refuse_constant(name: str) -> float:
    raise WireError(f"a non-finite number ({name})")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise WireError(f"a number out of range ({text[:20]})")
    return value


def load_json(text: Any, max_chars: int = MAX_CHARS, max_depth: int = MAX_DEPTH) -> Any:
    """The JSON value of ``text``, bounded: at most ``max_chars`` characters and
    ``max_depth`` levels of nesting, finite numbers only.  Raises :class:`WireError`."""
    if not isinstance(text, str):
        raise WireError(f"not text but {type(text).__name__}")
    if len(text) > max_chars:
        raise WireError(f"{len(text)} characters, more than {max_chars}")
    check_depth(text, max_depth)
    try:
        return json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
    except WireError:
        raise
    except (ValueError, RecursionError) as exc:      # ValueError: JSONDecodeError, int digits
        raise WireError(f"not JSON ({exc})") from None


@dataclass(frozen=True)
class Field:
    """One key of a JSON object: its type and, for numbers, the range [lo, hi]; for text
    the longest length [characters]."""

    kind: type
    lo: float = -math.inf
    hi: float = math.inf
    max_len: int = 1024


def read_fields(text: Any, fields: Mapping[str, Field], max_chars: int = MAX_CHARS,
                max_depth: int = MAX_DEPTH) -> dict[str, Any]:
    """The object in ``text`` with exactly the keys of ``fields``, each of its type (an
    ``int`` field takes integers only, a ``float`` field integers too) and within its range.
    Raises :class:`WireError` naming the key, the value and what was expected."""
    data = load_json(text, max_chars, max_depth)
    if not isinstance(data, dict):
        raise WireError(f"not a JSON object but {type(data).__name__}")
    missing = sorted(set(fields) - set(data))
    unknown = sorted(set(data) - set(fields))
    if missing or unknown:
        raise WireError("keys " + ", ".join(
            ([f"missing: {', '.join(missing)}"] if missing else [])
            + ([f"unknown: {', '.join(k[:40] for k in unknown[:5])}"] if unknown else [])))
    out: dict[str, Any] = {}
    for key, f in fields.items():
        value = data[key]
        if f.kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, f.kind) or (f.kind is not bool and isinstance(value, bool)):
            raise WireError(f"{key} = {str(value)[:40]!r}: expected {f.kind.__name__}")
        if isinstance(value, (int, float)) and not f.lo <= value <= f.hi:
            raise WireError(f"{key} = {str(value)[:40]}: expected within [{f.lo:g}, {f.hi:g}]")
        if isinstance(value, str) and len(value) > f.max_len:
            raise WireError(f"{key}: {len(value)} characters, more than {f.max_len}")
        out[key] = value
    return out
