"""Where the nominal model parts from the records: by place, by phase, by observable.

Places, from the model's own geometry at the frame's time (first match wins):

* ``tool contact``: the foot point lies within one thickness of the tool's outline;
* ``top edge``: on the cake top or its rounded edge (z above height - fillet radius,
  x < one thickness);
* ``cake bottom``: within three thicknesses of the wall's foot (x = 0, z = 0);
* ``workplane``: lower than 1.5 thicknesses;
* ``free span``: the rest.

Phases, from the driving tool path and the model's tool contact:
``approach`` (before the tool first touches the sheet), ``forced deformation``
(the tool moves and touches it), ``dwell`` (it stands still and touches it),
``release`` (it moves and touches it after its last dwell), ``settle`` (contact
over).  Each group's entry carries its RMS, its systematic RMS
sqrt(max(mean r^2 - s^2, 0)) (the ranking key) and its mean (the sign: + the
sheet is measured on the outer side of the model).
"""
from __future__ import annotations

import math

import numpy as np

from ..planning.scenarios import PHASES as _PHASE_WORDS
from ..sheet.metrics import touching_tool
from ..sheet.tools import tool_shape

PLACES = ("top edge", "free span", "tool contact", "cake bottom", "workplane")
#: The movement's phases in their words (planning.scenarios.PHASES, the one vocabulary),
#: in order: a phase label is an index into this.
PHASES = tuple(_PHASE_WORDS.values())


def places(data, res, run) -> np.ndarray:
    """Place label index (into PLACES) of each measured point."""
    sc = data.record.scenario
    th = sc.sheet.thickness
    foot = res.foot
    label = np.full(len(foot), 1)
    label[np.hypot(foot[:, 0], foot[:, 1]) < 3 * th] = 3
    label[(foot[:, 1] < 1.5 * th) & (label == 1)] = 4
    label[(foot[:, 1] > sc.cake.height - sc.cake.fillet_radius) & (foot[:, 0] < th)] = 0
    shape = tool_shape(sc.tool)
    shift = np.asarray(sc.effects.tool_offset, float)
    times = data.record.profile_t
    for f in np.unique(data.point_frame):
        sel = data.point_frame == f
        pose = data.path.position(times[f]) + shift
        d, _ = shape.signed_distance(foot[sel], pose)
        near = d < th
        lab = label[sel]
        lab[near] = 2
        label[sel] = lab
    return label


def phases(data, run) -> np.ndarray:
    """Phase label index (into PHASES) of each profile frame."""
    t = data.record.profile_t
    touching = np.any(touching_tool(run.tool_contact), axis=1)
    k = np.clip(np.searchsorted(run.t, t), 0, run.t.size - 1)
    contact = touching[k]
    # the tool's speed [m/s] over +-1 s of the reconstructed path: the measured poses'
    # jitter (tens of um) stays below a tenth of the movement's speed, any move above it
    h = 1.0
    pos = np.array([data.path.position(x) for x in np.r_[t - h, t + h]]).reshape(2, -1, 2)
    speed = np.hypot(*(pos[1] - pos[0]).T) / (2 * h)
    moving = speed > 0.1 * data.record.scenario.movement.speed
    out = np.full(t.size, 0)
    if not contact.any():
        return out
    first = int(np.argmax(contact))
    last = int(len(contact) - 1 - np.argmax(contact[::-1]))
    still = np.flatnonzero(contact & ~moving)
    last_dwell = int(still[-1]) if still.size else first
    for i in range(first, t.size):
        if i > last:
            out[i] = 4
        elif not moving[i]:
            out[i] = 2
        elif i > last_dwell:
            out[i] = 3
        else:
            out[i] = 1
    return out


def _entry(kind: str, name: str, r: np.ndarray, s: float, unit: str) -> dict:
    ms = float(np.mean(r ** 2)) if r.size else math.nan
    return {"kind": kind, "name": name, "n": int(r.size), "unit": unit,
            "rms": math.sqrt(ms) if r.size else None,
            "systematic_rms": math.sqrt(max(ms - s * s, 0.0)) if r.size else None,
            "mean": float(np.mean(r)) if r.size else None,
            "relative": math.sqrt(max(ms - s * s, 0.0)) / s if r.size else None}


def rank(data, res, runs, sp: float, sf: float) -> list[dict]:
    """Places, phases and observables, ranked by systematic RMS relative to the noise."""
    entries = []
    prof = [r.profile for r in res]
    pl = [places(d, r, run) for d, r, run in zip(data, res, runs)]
    ph = [phases(d, run)[d.point_frame] for d, run in zip(data, runs)]
    allp, allpl, allph = np.concatenate(prof), np.concatenate(pl), np.concatenate(ph)
    for i, name in enumerate(PLACES):
        entries.append(_entry("place", name, allp[allpl == i], sp, "m"))
    for i, name in enumerate(PHASES):
        entries.append(_entry("phase", name, allp[allph == i], sp, "m"))
    entries.append(_entry("observable", "profile", allp, sp, "m"))
    forces = [r.force.reshape(-1) for r in res if r.force is not None]
    if forces:
        entries.append(_entry("observable", "tool force", np.concatenate(forces), sf, "N"))
    entries = [e for e in entries if e["n"] > 0]
    entries.sort(key=lambda e: -(e["relative"] or 0.0))
    for i, e in enumerate(entries):
        e["rank"] = i + 1
    return entries
