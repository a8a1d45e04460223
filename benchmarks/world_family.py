#!/usr/bin/env python3
"""The sizes of the dynamic world's form variations (issue 46, point 1;
:mod:`rheo_shaping_validation.worlds.forms`) against its default form, in the sensors' units.

For each variation at the low and the high end of its drawn range (a sign: +), on the
default cell, movements given (default 1 and 3), 120 s, a drawn laying: the tool force's
RMS difference [mN] and the profile's RMS distance [mm] to the default form's run (the
same laying and numerics; :func:`rheo_shaping_validation.worlds.verify.run_gap`).  The sensor
variations change no run: the load cell's filter is sized as the RMS of the filtered
force minus the force [mN]; the tool's occlusion as the share of the points a frame loses
while the tool touches the sheet, and the largest run of hidden sheet [mm].

``PYTHONPATH=. python benchmarks/world_family.py [--movements 1,3] [--process-time 120]
[--json FILE]`` (about 10 minutes on one quiet core at 120 s).
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping_validation.worlds.dynamic import run_world
from rheo_shaping_validation.worlds.forms import VARIATIONS, FormParams, Variation, low_pass
from rheo_shaping_validation.worlds.params import LayParams
from rheo_shaping_validation.worlds.sensors import SensorParams, _visible
from rheo_shaping_validation.worlds.verify import run_gap

LAY = LayParams(mode2=0.3, lift=1e-3, prestrain=-2e-3)
SENSOR = (Variation.LOAD_CELL_FILTER, Variation.TOOL_OCCLUSION)


def form_at(v: Variation, value: float) -> FormParams:
    kw: dict = {v.value: value}
    if v is Variation.THICKNESS_VARIATION:
        kw["thickness_seed"] = 7
    return FormParams(**kw)


def sensor_size(v: Variation, value: float, run) -> dict:
    if v is Variation.LOAD_CELL_FILTER:
        d = low_pass(run.t, run.tool_force, value) - run.tool_force
        return {"force_rms_mN": 1e3 * float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))))}
    sp = SensorParams()
    hidden, spans = [], []
    for k in np.flatnonzero(run.tool_touches())[::25]:
        nodes = run.nodes(int(k))
        cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(nodes, axis=0).T))))
        s = np.arange(0.0, cum[-1], sp.profile_spacing)
        pts = np.c_[np.interp(s, cum, nodes[:, 0]), np.interp(s, cum, nodes[:, 1])]
        seen = _visible(run, pts, float(run.t[k]), value, 0.0)
        hidden.append(1.0 - seen.mean())
        spans.append(sp.profile_spacing * float((~seen).sum()))
    return {"hidden_share_touching": float(np.mean(hidden)) if hidden else 0.0,
            "hidden_span_max_mm": 1e3 * max(spans, default=0.0)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--movements", default="1,3")
    ap.add_argument("--process-time", type=float, default=120.0)
    ap.add_argument("--json", default=None, help="write the sizes to this file")
    a = ap.parse_args()
    out: dict = {"process_time_s": a.process_time, "lay": vars(LAY), "sizes": []}
    for m in (int(x) for x in a.movements.split(",")):
        p = CellParams()
        p = replace(p, movement=replace(p.movement, number=m, process_time=a.process_time))
        path = movement_plan(p)
        t0 = time.monotonic()
        ref = run_world(p, path, lay=LAY)
        print(f"movement {m}: default form {time.monotonic() - t0:.0f} s", flush=True)
        for v, r in VARIATIONS.items():
            for end, value in (("low", r.low), ("high", r.high)):
                row = {"movement": m, "variation": v.value, "end": end, "value": value}
                if v in SENSOR:
                    row.update(sensor_size(v, value, ref))
                else:
                    t0 = time.monotonic()
                    g = run_gap(ref, run_world(p, path, lay=LAY, form=form_at(v, value)))
                    row.update(force_rms_mN=1e3 * g.force_rms, profile_rms_mm=1e3 * g.profile_rms,
                               profile_max_mm=1e3 * g.profile_max, F_max_N=g.F_max,
                               wall_s=time.monotonic() - t0)
                out["sizes"].append(row)
                print(json.dumps(row), flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
