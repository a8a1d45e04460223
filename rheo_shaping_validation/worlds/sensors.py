"""The dynamic world's own measurement model: a world run as a cell's sensors report it.

The robot reports the commanded tool pose (``pose_rate``, Gaussian noise
``pose_noise``), a vision system samples points along the sheet's centreline
(``profile_rate`` frames, one point every ``profile_spacing`` of arc length from a
random start, noise ``profile_noise``, lost frames and points), and a load cell
gives the sheet's force on the tool (``wrench_rate``, noise ``wrench_noise``),
each through its chain errors (the diagnosis's ``CHAIN`` knobs: vision offset,
load-cell bias, gain and lag) and the world's sensor effects (camera scale,
load-cell drift) and the form's sensor variations (the load cell's own low-pass, the
sheet hidden by the tool, :mod:`~rheo_shaping_validation.worlds.forms`).  The result is the
:class:`~rheo_shaping.records.record.Record` the diagnosis reads.  Written apart from
:mod:`rheo_shaping.records.measurement`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rheo_shaping.params.cell import CellParams, EffectsParams
from rheo_shaping.records.record import Record
from .dynamic import WorldRun, tool_vertices
from .forms import FormParams, low_pass
from .params import WorldEffects


@dataclass(frozen=True)
class SensorParams:
    """The cell's sensors (defaults: issue 26's independent records)."""

    profile_rate: float = 2.0        # Hz, vision frames
    profile_spacing: float = 3e-3    # m, between vision points along the centreline
    profile_noise: float = 2e-4      # m, per point and coordinate
    frame_dropout: float = 0.05      # fraction of frames lost
    point_dropout: float = 0.02      # fraction of points lost in a frame
    pose_rate: float = 50.0          # Hz, robot pose reports
    pose_noise: float = 5e-5         # m
    wrench_rate: float = 50.0        # Hz, load cell samples
    wrench_noise: float = 5e-3       # N


def _points_along(nodes: np.ndarray, spacing: float, start: float) -> np.ndarray:
    """Points every ``spacing`` [m] of arc length along polyline ``nodes`` from ``start``."""
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(nodes, axis=0).T))))
    s = np.arange(start, cum[-1], spacing)
    return np.c_[np.interp(s, cum, nodes[:, 0]), np.interp(s, cum, nodes[:, 1])]


def _centreline(run: WorldRun, t: float) -> np.ndarray:
    """The centreline (bonds included) at time ``t`` [s], linear between samples."""
    k = int(np.clip(np.searchsorted(run.t, t), 1, run.t.size - 1))
    w = float(np.clip((t - run.t[k - 1]) / (run.t[k] - run.t[k - 1]), 0.0, 1.0))
    return (1.0 - w) * run.nodes(k - 1) + w * run.nodes(k)


def _visible(run: WorldRun, pts: np.ndarray, t: float, blind: float, tilt: float) -> np.ndarray:
    """(M,) bool: centreline points ``pts`` [m] whose sheet surface is farther than ``blind``
    [m] from the tool's surface at time ``t`` [s] (the commanded pose plus the cell's tool
    offset): the tool hides the sheet it touches, and ``blind`` beyond, from the camera."""
    from .kernel import polygon_gap
    tx = float(np.interp(t, run.t, run.tool[:, 0])) + float(run.params.effects.tool_offset[0])
    tz = float(np.interp(t, run.t, run.tool[:, 1])) + float(run.params.effects.tool_offset[1])
    verts, rad = tool_vertices(run.params, tilt)
    r = 0.5 * run.params.sheet.thickness
    return np.array([polygon_gap(px - tx, pz - tz, verts, rad)[0] - r > blind
                     for px, pz in pts], dtype=bool)


def measure_world(run: WorldRun, path, sensors: SensorParams, rng: np.random.Generator,
                  chain: dict | None = None, extra: WorldEffects = WorldEffects(),
                  name: str = "", form: FormParams = FormParams()) -> Record:
    """The record of ``run`` (tool commanded on ``path``) through chain errors ``chain``
    (knob name -> value in its unit: ``vision.dx``, ``vision.dz`` [m], ``load_cell.bias_x``,
    ``load_cell.bias_z`` [N], ``load_cell.gain`` [-], ``load_cell.lag`` [s]) and the sensor
    effects of ``extra`` and ``form``'s sensor variations.  The record's scenario is the
    run's cell with every effect off."""
    ch = chain or {}
    sp = sensors
    t_end = float(run.t[-1])
    pose_t = np.arange(0.0, t_end + 1e-9, 1.0 / sp.pose_rate)
    pose = np.array([path.position(t) for t in pose_t], float)
    pose = pose + rng.normal(0.0, sp.pose_noise, pose.shape)
    frame_t = np.arange(0.0, t_end + 1e-9, 1.0 / sp.profile_rate)
    frame_t = frame_t[rng.random(frame_t.size) >= sp.frame_dropout]
    centre = np.asarray(extra.camera_centre, float)
    shift = np.array([ch.get("vision.dx", 0.0), ch.get("vision.dz", 0.0)])
    profiles = []
    for t in frame_t:
        pts = _points_along(_centreline(run, t), sp.profile_spacing,
                            rng.uniform(0.0, sp.profile_spacing))
        seen = (_visible(run, pts, t, form.tool_occlusion, extra.tool_tilt)
                if form.tool_occlusion > 0.0 else None)
        pts = centre + (1.0 + extra.camera_scale) * (pts - centre)     # camera scale error
        pts = pts + shift + rng.normal(0.0, sp.profile_noise, pts.shape)
        kept = rng.random(len(pts)) >= sp.point_dropout
        if seen is not None:
            kept &= seen
        profiles.append(pts[kept])
    wrench_t = np.arange(0.0, t_end + 1e-9, 1.0 / sp.wrench_rate)
    lagged = wrench_t - ch.get("load_cell.lag", 0.0)
    sensed = low_pass(run.t, run.tool_force, form.load_cell_filter)   # the cell's own filter
    force = np.c_[np.interp(lagged, run.t, sensed[:, 0]),
                  np.interp(lagged, run.t, sensed[:, 1])]
    bias = np.array([ch.get("load_cell.bias_x", 0.0), ch.get("load_cell.bias_z", 0.0)])
    drift = extra.load_cell_drift * np.asarray(extra.drift_direction, float)
    wrench = ((1.0 + ch.get("load_cell.gain", 0.0)) * force + bias + wrench_t[:, None] * drift
              + rng.normal(0.0, sp.wrench_noise, force.shape))
    return Record(scenario=replace(run.params, effects=EffectsParams()), pose_t=pose_t,
                  pose_xz=pose, profile_t=frame_t, profiles=tuple(profiles), wrench_t=wrench_t,
                  wrench_xz=wrench, name=name)


def world_record(params: CellParams, path, rng: np.random.Generator, **kw) -> tuple:
    """Convenience: :func:`~rheo_shaping_validation.worlds.dynamic.run_world` then
    :func:`measure_world`; keyword arguments ``lay``, ``extra``, ``numerics``, ``sensors``,
    ``chain``, ``name``, ``form``.  Returns (record, run)."""
    from .dynamic import run_world
    extra = kw.get("extra", WorldEffects())
    form = kw.get("form", FormParams())
    run_kw = {k: kw[k] for k in ("lay", "numerics") if k in kw}
    run = run_world(params, path, extra=extra, form=form, **run_kw)
    rec = measure_world(run, path, kw.get("sensors", SensorParams()), rng, kw.get("chain"),
                        extra, kw.get("name", ""), form)
    return rec, run
