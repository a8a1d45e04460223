"""Records from CSV tables, for cells whose robot and vision system write tables.

Formats (a header row, then one row per sample; SI units; ``t`` in seconds,
any origin: t = 0 becomes the first pose sample):

* pose:    ``t,x,z``     the tool reference point [m] (at least 2 rows);
* profile: ``t,x,z``     one row per measured point [m]; the rows of a frame
  share its ``t`` and run from the cake-top bond to the workplane bond;
* wrench:  ``t,fx,fz``   force of the sheet on the tool [N] (optional).

Errors name the file, the line and the column; nothing is written.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..params.config import ConfigError, load_cell
from .record import Record
from .bag import RecordError, _assemble


def read_table(path: str | Path, columns: tuple[str, ...]) -> np.ndarray:
    """Rows of ``columns`` as floats; :class:`RecordError` naming file, line and column."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise RecordError(f"{p}: cannot be read ({exc.strerror or exc})") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise RecordError(f"{p}: empty file; expected a header row {','.join(columns)}")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in columns if c not in header]
    if missing:
        raise RecordError(f"{p}: line 1: missing column '{missing[0]}' (header "
                          f"{','.join(header)}; "
                          f"expected {','.join(columns)})")
    idx = [header.index(c) for c in columns]
    out = []
    for line, row in enumerate(rows[1:], start=2):
        if not row or all(not x.strip() for x in row):
            continue
        vals = []
        for c, i in zip(columns, idx):
            if i >= len(row):
                raise RecordError(f"{p}: line {line}, column '{c}': missing value")
            try:
                v = float(row[i])
            except ValueError:
                raise RecordError(
                    f"{p}: line {line}, column '{c}': {row[i]!r} is not a number") from None
            if not math.isfinite(v):
                raise RecordError(
                    f"{p}: line {line}, column '{c}': {row[i]!r} is not a finite number")
            vals.append(v)
        out.append(vals)
    a = np.array(out, float).reshape(-1, len(columns))
    bad = np.flatnonzero(np.diff(a[:, 0]) < 0)
    if bad.size:
        raise RecordError(f"{p}: line {bad[0] + 3}, column 't': times must not decrease "
                          f"({a[bad[0] + 1, 0]!r} after {a[bad[0], 0]!r})")
    return a


def import_csv(scenario_yaml: str | Path, pose_csv: str | Path, profile_csv: str | Path,
               wrench_csv: str | Path | None = None, name: str = "") -> Record:
    """A :class:`Record` from CSV tables and the nominal cell's params file."""
    try:
        scenario = load_cell(scenario_yaml)
    except ConfigError as exc:
        raise RecordError(str(exc)) from None
    pose = read_table(pose_csv, ("t", "x", "z"))
    prof = read_table(profile_csv, ("t", "x", "z"))
    if len(pose) < 2:
        raise RecordError(f"{pose_csv}: {len(pose)} pose row(s); expected at least 2")
    frames = []
    if len(prof):
        cut = np.flatnonzero(np.diff(prof[:, 0]) > 0) + 1
        for chunk in np.split(prof, cut):
            frames.append((float(chunk[0, 0]), chunk[:, 1:]))
    if len(frames) < 2:
        raise RecordError(f"{profile_csv}: {len(frames)} profile frame(s); expected at least 2")
    data = {"/tool/pose": [tuple(r) for r in pose], "/sheet/measured_profile": frames,
            "/tool/wrench": [tuple(r) for r in read_table(wrench_csv,
                                                          ("t", "fx",
                                                           "fz"))] if wrench_csv else []}
    return _assemble(scenario, data, name or Path(pose_csv).stem, Path(pose_csv).parent)
