"""Material test data: creep residual tables, creep curves, tensile curves (CSV).

Every format (documented in ``docs/material.md``) is a comma-separated text
file in SI units:

* lines starting with ``#`` are comments; a comment ``# key: value`` with a
  key from :data:`METADATA_KEYS` sets a property of the data (``speed_m_per_s``,
  ``length_m``, ``force_hold``);
* the first other line is the header: column names, in any order (extra
  columns are ignored);
* then one sample per line.  Blank lines are skipped.

The header decides the kind (:func:`read_material_file`):

=================  =========================================  =====================
kind               required columns                           class
=================  =========================================  =====================
creep residuals    ``F_N, t1_s, x_residual_m`` (``test``)     :class:`CreepResiduals`
creep curve        ``t_s, F_N, x_m``                          :class:`CreepCurve`
tensile curve      ``t_s, F_N``                               :class:`TensileCurve`
=================  =========================================  =====================

A malformed file raises :class:`DataFormatError` naming the file, the line and
the column.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence, overload

import numpy as np

from ..material.three_element import SPECIMEN_LENGTH_M

#: Metadata comment keys and their meaning.
METADATA_KEYS = {
    "speed_m_per_s": "tensile curve: constant pull speed [m/s]",
    "length_m": "rest length of the tested strip [m] (default 0.1)",
    "force_hold": "creep curve: 'step' (force held to the next sample, default) or 'linear'",
}

CREEP_RESIDUAL_COLUMNS = ("F_N", "t1_s", "x_residual_m")
CREEP_CURVE_COLUMNS = ("t_s", "F_N", "x_m")
TENSILE_COLUMNS = ("t_s", "F_N")


class DataFormatError(ValueError):
    """A data file that cannot be read; the message names file, line and column."""


@dataclass(frozen=True, eq=False)
class CreepResiduals:
    """Non-recoverable elongations after creep tests (paper Table 1, Eq. 9-10).

    Per test: constant ``force`` F [N] held for ``t1`` [s], then removed; the
    ``residual`` elongation x2(t -> inf) [m].  ``length`` [m]: rest length.
    """

    force: np.ndarray
    t1: np.ndarray
    residual: np.ndarray
    length: float = SPECIMEN_LENGTH_M
    source: str = ""
    labels: tuple = field(default=())

    def __len__(self) -> int:
        return int(self.residual.size)


@dataclass(frozen=True, eq=False)
class CreepCurve:
    """A creep(-recovery) test: imposed ``force`` [N] and measured ``elongation`` [m] at ``t`` [s].

    ``hold="step"``: force[i] acts from t[i] to t[i+1]; ``"linear"``: linear between samples.
    """

    t: np.ndarray
    force: np.ndarray
    elongation: np.ndarray
    length: float = SPECIMEN_LENGTH_M
    hold: str = "step"
    source: str = ""


@dataclass(frozen=True, eq=False)
class TensileCurve:
    """A tensile test at constant ``speed`` [m/s]: measured ``force`` [N] at ``t`` [s].

    The pull starts at ``t = 0`` from rest; samples with ``t <= 0`` are the
    load cell at rest (they show its offset).
    """

    t: np.ndarray
    force: np.ndarray
    speed: float
    length: float = SPECIMEN_LENGTH_M
    source: str = ""


def _where(path, line: int, col: int | None = None, name: str | None = None) -> str:
    s = f"{path}: line {line}"
    if col is not None:
        s += f", column {col}" + (f" ({name})" if name else "")
    return s


def _parse(path: str | os.PathLike) -> tuple[dict, list[str], list[tuple[int, list[str]]], int]:
    """(metadata with line numbers, header names, [(line number, fields)], header line)."""
    p = Path(path)
    if not p.exists():
        raise DataFormatError(f"{path}: no such file")
    if p.is_dir():
        raise DataFormatError(f"{path}: is a directory, expected a CSV file")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DataFormatError(f"{path}: not a UTF-8 text file ({exc.reason})") from None
    meta: dict[str, tuple[str, int]] = {}
    header: list[str] | None = None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    for no, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if ":" in body:
                key, _, value = body.partition(":")
                key = key.strip()
                if key in METADATA_KEYS:
                    meta[key] = (value.strip(), no)
            continue
        fields = [f.strip() for f in line.split(",")]
        if header is None:
            header, header_line = fields, no
            for i, name in enumerate(fields, start=1):
                if not name:
                    raise DataFormatError(
                        f"{_where(path, no, i)}: empty column name in the header")
                if fields.index(name) != i - 1:
                    raise DataFormatError(
                        f"{_where(path, no, i, name)}: column name repeated in the header")
            continue
        rows.append((no, fields))
    if header is None:
        raise DataFormatError(f"{path}: no header line (only comments or empty)")
    return meta, header, rows, header_line


@overload
def _meta_float(path, meta: dict, key: str, default: float) -> float: ...
@overload
def _meta_float(path, meta: dict, key: str, default: None) -> float | None: ...


def _meta_float(path, meta: dict, key: str, default: float | None) -> float | None:
    """The positive number of metadata ``key``, else ``default``."""
    if key not in meta:
        return default
    value, no = meta[key]
    try:
        v = float(value)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0.0):
        raise DataFormatError(
            f"{_where(path, no)}: metadata {key} = {value!r}: expected a positive number")
    return v


def _columns(path, header: list[str], header_line: int, rows, required: tuple[str, ...],
             checks: dict[str, str]) -> dict[str, np.ndarray]:
    missing = [c for c in required if c not in header]
    if missing:
        raise DataFormatError(f"{_where(path, header_line)}: header {','.join(header)} lacks "
                              "column(s) "
                              f"{', '.join(missing)} (expected {', '.join(required)})")
    if not rows:
        raise DataFormatError(f"{path}: no data lines after the header (line {header_line})")
    idx = {c: header.index(c) for c in required}
    out = {c: np.empty(len(rows)) for c in required}
    for k, (no, fields) in enumerate(rows):
        if len(fields) != len(header):
            col = min(len(fields), len(header)) + 1
            raise DataFormatError(f"{_where(path, no, col)}: {len(fields)} fields, expected "
                                  f"{len(header)} "
                                  f"(header {','.join(header)})")
        for c, i in idx.items():
            s = fields[i]
            try:
                v = float(s)
            except ValueError:
                raise DataFormatError(
                    f"{_where(path, no, i + 1, c)}: {s!r} is not a number") from None
            rule = checks.get(c, "finite")
            ok = math.isfinite(v) and (rule == "finite" or (rule == "positive" and v > 0.0)
                                       or (rule == "non-negative" and v >= 0.0))
            if not ok:
                raise DataFormatError(
                    f"{_where(path, no, i + 1, c)}: {s!r}: expected a {rule} number")
            out[c][k] = v
    return out


def _increasing(path, rows, header: list[str], t: np.ndarray, name: str = "t_s") -> None:
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        k = int(bad[0]) + 1
        col = header.index(name) + 1
        raise DataFormatError(f"{_where(path, rows[k][0], col, name)}: {t[k]!r} is not after the "
                              "previous "
                              f"sample {t[k - 1]!r} (time must increase strictly)")


def _kind(header: list[str]) -> str:
    if all(c in header for c in CREEP_RESIDUAL_COLUMNS):
        return "creep_residuals"
    if all(c in header for c in CREEP_CURVE_COLUMNS):
        return "creep_curve"
    if all(c in header for c in TENSILE_COLUMNS):
        return "tensile_curve"
    return "unknown"


def read_creep_residuals(path: str | os.PathLike) -> CreepResiduals:
    """Read a creep residual table (columns ``F_N, t1_s, x_residual_m``, optional ``test``)."""
    meta, header, rows, hl = _parse(path)
    cols = _columns(path, header, hl, rows, CREEP_RESIDUAL_COLUMNS,
                    {"F_N": "positive", "t1_s": "positive", "x_residual_m": "positive"})
    labels = tuple(f[header.index("test")] for _, f in rows) if "test" in header else ()
    return CreepResiduals(cols["F_N"], cols["t1_s"], cols["x_residual_m"],
                          _meta_float(path, meta, "length_m", SPECIMEN_LENGTH_M), str(path),
                          labels)


def read_creep_curve(path: str | os.PathLike) -> CreepCurve:
    """Read a creep curve (columns ``t_s, F_N, x_m``; metadata ``force_hold``)."""
    meta, header, rows, hl = _parse(path)
    cols = _columns(path, header, hl, rows, CREEP_CURVE_COLUMNS, {"F_N": "non-negative"})
    _increasing(path, rows, header, cols["t_s"])
    hold = "step"
    if "force_hold" in meta:
        hold, no = meta["force_hold"]
        if hold not in ("step", "linear"):
            raise DataFormatError(
                f"{_where(path, no)}: metadata force_hold = {hold!r}: expected step or linear")
    return CreepCurve(cols["t_s"], cols["F_N"], cols["x_m"],
                      _meta_float(path, meta, "length_m", SPECIMEN_LENGTH_M), hold, str(path))


def read_tensile_curve(path: str | os.PathLike, speed: float | None = None,
                       default_speed: float | None = None) -> TensileCurve:
    """Read a tensile curve (columns ``t_s, F_N``).

    The speed is ``speed`` if given (a file whose ``speed_m_per_s`` metadata
    contradicts it is refused), else the file's metadata, else
    ``default_speed``.
    """
    meta, header, rows, hl = _parse(path)
    cols = _columns(path, header, hl, rows, TENSILE_COLUMNS, {})
    _increasing(path, rows, header, cols["t_s"])
    file_speed = _meta_float(path, meta, "speed_m_per_s", None)
    if file_speed is not None and speed is not None and not math.isclose(file_speed, speed,
                                                                         rel_tol=1e-9):
        raise DataFormatError(f"{_where(path, meta['speed_m_per_s'][1])}: speed_m_per_s = "
                              f"{file_speed!r} "
                              f"contradicts the speed given, {speed!r} m/s")
    v = speed if speed is not None else (file_speed if file_speed is not None else default_speed)
    if v is None:
        raise DataFormatError(
            f"{path}: no pull speed (give it, or a '# speed_m_per_s: ...' comment)")
    if not (math.isfinite(v) and v > 0.0):
        raise DataFormatError(f"{path}: speed = {v!r} m/s: expected a positive number")
    if not (cols["t_s"] > 0.0).any():
        raise DataFormatError(f"{path}: no samples after the start of the pull (t_s > 0)")
    return TensileCurve(cols["t_s"], cols["F_N"], v,
                        _meta_float(path, meta, "length_m", SPECIMEN_LENGTH_M), str(path))


def material_file_kind(path: str | os.PathLike) -> str:
    """``"creep_residuals"``, ``"creep_curve"``, ``"tensile_curve"`` or ``"unknown"`` (by the
    header)."""
    return _kind(_parse(path)[1])


def read_material_file(path: str | os.PathLike, speed: float | None = None,
                       default_speed: float | None = None):
    """Read any of the three formats, telling them apart by their header."""
    _, header, _, hl = _parse(path)
    kind = _kind(header)
    if kind == "creep_residuals":
        return read_creep_residuals(path)
    if kind == "creep_curve":
        return read_creep_curve(path)
    if kind == "tensile_curve":
        return read_tensile_curve(path, speed, default_speed)
    raise DataFormatError(f"{_where(path, hl)}: header {','.join(header)} is none of the known "
                          "formats "
                          f"({','.join(CREEP_RESIDUAL_COLUMNS)} | {','.join(CREEP_CURVE_COLUMNS)} "
                          "| "
                          f"{','.join(TENSILE_COLUMNS)})")


def write_tensile_curve(path: str | os.PathLike, curve: TensileCurve, comments: Sequence[str] = (),
                        overwrite: bool = False) -> None:
    """Write ``curve`` in the tensile format; refuses to replace a file unless ``overwrite``."""
    p = Path(path)
    if p.exists() and not overwrite:
        raise FileExistsError(f"{path}: exists (not overwritten)")
    lines = [f"# {c}" for c in comments]
    lines += [f"# speed_m_per_s: {curve.speed!r}", f"# length_m: {curve.length!r}", "t_s,F_N"]
    lines += [f"{t:.10g},{F:.6g}" for t, F in zip(curve.t, curve.force)]
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
