#!/usr/bin/env python3
"""The dynamic world (rheo_shaping_validation.worlds) on the default cell, movements 1-4, 120 s:

* its convergence: 50 vs 100 masses and dt vs dt/2 (at 50 masses), for the default laying
  and a drawn one, as the tool force's RMS difference [mN] against the load cell's noise
  (5 mN) and the profile's RMS distance [mm] against the camera's (0.2 mm);
* Table 2: F_max at 63 masses against the paper's;
* the model-form gap: the sheet model (the project's, quasi-static, settled start) against
  the world on the same cell, in the same units, over the run and in the first 2 s (the
  release and settle) and after (what a diagnosis of effect-free records of the world sees
  as the floor of form);
* wall time per 120 s run.

``PYTHONPATH=. python benchmarks/world_convergence.py [--json]`` (about 1-2 minutes on one
core).
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.simulation import run_scenario
from rheo_shaping.study.reproduce import PAPER
from rheo_shaping_validation.worlds.dynamic import run_world
from rheo_shaping_validation.worlds.params import LayParams, WorldNumerics
from rheo_shaping_validation.worlds.verify import polyline_distance, run_gap

LAYS = {"default": LayParams(), "drawn": LayParams(mode2=0.3, lift=1e-3, prestrain=-2e-3)}


def model_gap(world, model) -> dict:
    """The sheet model's run against the world's: tool force RMS [N], profile RMS [m]."""
    f = np.c_[np.interp(world.t, model.t, model.tool_force[:, 0]),
              np.interp(world.t, model.t, model.tool_force[:, 1])]
    df = np.hypot(*(world.tool_force - f).T)
    per = []
    for t in np.arange(0.0, world.t[-1] + 1e-9, 0.5):
        k = int(np.searchsorted(world.t, t - 1e-9))
        j = int(np.clip(np.searchsorted(model.t, t), 0, model.t.size - 1))
        per.append(np.sqrt(np.mean(polyline_distance(world.nodes(k), model.nodes(j)) ** 2)))
    per = np.array(per)
    early = np.arange(per.size) * 0.5 < 2.0
    return {"force_rms_mN": 1e3 * float(np.sqrt(np.mean(df ** 2))),
            "profile_rms_mm": 1e3 * float(np.sqrt(np.mean(per ** 2))),
            "profile_rms_first_2s_mm": 1e3 * float(np.sqrt(np.mean(per[early] ** 2))),
            "profile_rms_after_2s_mm": 1e3 * float(np.sqrt(np.mean(per[~early] ** 2)))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out: dict = {"convergence": [], "table2": {}, "model_form": {}, "wall_s": {}}
    p0 = CellParams()
    for mv in (1, 2, 3, 4):
        p = replace(p0, movement=replace(p0.movement, number=mv))
        path = movement_plan(p)
        for lay_name, lay in LAYS.items():
            ref = run_world(p, path, lay=lay, numerics=WorldNumerics(n_masses=50))
            for what, nm in (("N 50 -> 100", WorldNumerics(n_masses=100)),
                             ("dt -> dt/2", WorldNumerics(n_masses=50, dt=5e-4))):
                g = run_gap(ref, run_world(p, path, lay=lay, numerics=nm))
                out["convergence"].append({
                    "movement": mv, "lay": lay_name, "refinement": what,
                    "force_rms_mN": 1e3 * g.force_rms, "force_max_mN": 1e3 * g.force_max,
                    "profile_rms_mm": 1e3 * g.profile_rms, "F_max_change": g.F_max / ref.F_max})
        t0 = time.perf_counter()
        run = run_world(p, path)
        out["wall_s"][str(mv)] = time.perf_counter() - t0
        ref = PAPER["movements"][str(mv)]["F_max"]
        out["table2"][str(mv)] = {"F_max": run.F_max, "paper": ref, "rel": run.F_max / ref - 1}
        model = run_scenario(p, path)
        out["model_form"][f"{mv} default"] = model_gap(run, model)
        out["model_form"][f"{mv} drawn"] = model_gap(run_world(p, path, lay=LAYS["drawn"]), model)
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print("convergence (movement, laying, refinement: tool force RMS / max [mN], profile RMS "
          "[mm], F_max change)")
    for r in out["convergence"]:
        print(f"  {r['movement']} {r['lay']:8s} {r['refinement']:12s} {r['force_rms_mN']:6.2f} / "
              f"{r['force_max_mN']:6.1f}  {r['profile_rms_mm']:.3f}  "
              f"{100 * r['F_max_change']:+.2f} %")
    print("Table 2 (63 masses): F_max [N] world / paper")
    for k, r in out["table2"].items():
        print(f"  {k}: {r['F_max']:.3f} / {r['paper']:.3f} ({100 * r['rel']:+.1f} %), "
              f"{out['wall_s'][k]:.1f} s")
    print("the sheet model against the world (same cell; movement, laying): tool force RMS [mN], "
          "profile RMS [mm]: all, first 2 s, after 2 s")
    for k, r in out["model_form"].items():
        print(f"  {k:10s}: {r['force_rms_mN']:.1f}  {r['profile_rms_mm']:.3f}  "
              f"{r['profile_rms_first_2s_mm']:.3f}  {r['profile_rms_after_2s_mm']:.3f}")


if __name__ == "__main__":
    main()
