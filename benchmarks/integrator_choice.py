#!/usr/bin/env python3
"""Why the sheet is stepped implicitly: explicit vs implicit on the same cell, measured.

The sheet is stiff: gram masses on links of ~1.5e3 N/m (period ~5 ms), contacts
that must not penetrate more than 1e-5 m (a penalty of ~1e7 N/m: period
~0.1 ms), against a creep time c2/k1 = 13.7 s and a 120 s process.  This
script runs the default cell's sheet sagging under gravity (the settle, with
inertia) for ``--window`` seconds with

* an explicit symplectic-Euler integrator of the same forces (links with the
  exact Maxwell update, the same penalty contacts), at the largest stable step
  for a given contact stiffness, and
* the project's implicit step (backward Euler on the incremental potential),

and prints, for each, the time step, the wall time per simulated second, the
largest penetration and the projected wall time of a 120 s process; then the
implicit step's quasi-static process with long steps.  ``--json`` prints one
object.
"""
from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from rheo_shaping.sheet.geometry import Cake, Workplane
from rheo_shaping.material.three_element import elongation_step
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.chain import Obstacle, SheetModel
from rheo_shaping.sheet.simulation import build_chain, run_scenario, settle
import rheo_shaping.sheet.simulation as simulation


def explicit_settle(params: CellParams, kc: float, window: float, safety: float = 0.5):
    """Symplectic Euler with penalty contacts; returns (dt, wall, max penetration, x)."""
    c, x0 = build_chain(params)
    cake = Cake(params.cake.height, params.cake.fillet_radius, params.cake.radius)
    plane = Workplane()
    m = c.mass[:, None]
    k_link = float(np.max(c.k1))
    # stability of the stiffest oscillator: a sphere between two links and a contact
    omega = np.sqrt((4.0 * k_link + kc) / float(np.min(c.mass)))
    dt = safety * 2.0 / omega
    n = int(np.ceil(window / dt))
    x, v = x0.copy(), np.zeros_like(x0)
    e1 = np.zeros(c.rest_length.size)
    p = np.zeros_like(e1)
    lam = c.rest_length.copy()
    g = np.array([0.0, -c.gravity])
    worst = 0.0
    wall = time.perf_counter()
    for _ in range(n):
        nodes = np.vstack((c.anchor_top, x, c.anchor_bottom))
        d = np.diff(nodes, axis=0)
        l = np.hypot(d[:, 0], d[:, 1])  # noqa: E741
        F, e1, p = elongation_step(c.k1, c.c1, c.c2, e1, p, l - lam, dt)
        lam = c.rest_length + e1 + p
        f = (F / l)[:, None] * d
        force = f[1:] - f[:-1] + m * g
        for shape in (cake, plane):
            dist, nrm = shape.signed_distance(x)
            pen = np.maximum(c.radius - dist, 0.0)
            worst = max(worst, float(pen.max()))
            force += (kc * pen)[:, None] * nrm
        v += dt * force / m
        x += dt * v
    return dt, time.perf_counter() - wall, worst, x


def implicit_settle(params: CellParams, window: float, dt: float):
    c, x0 = build_chain(params)
    sp = params.solver
    model = SheetModel(c, [Obstacle("cake", Cake(params.cake.height, params.cake.fillet_radius,
                                                 params.cake.radius)),
                           Obstacle("workplane", Workplane())], sp.contact_stiffness, sp.force_tol)
    wall = time.perf_counter()
    st = settle(model, x0, window, dt)
    wall = time.perf_counter() - wall
    worst = 0.0
    for ob in model.obstacles:
        dist, _ = ob.shape.signed_distance(st.x)
        worst = max(worst, float(np.max(c.radius - dist)))
    return wall, max(worst, 0.0), st.x


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--window", type=float, default=0.2,
                    help="simulated settle window [s] (default 0.2)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    params = CellParams()
    rows = []
    for kc in (1e4, 1e5, 1e7):
        dt, wall, pen, x_exp = explicit_settle(params, kc, args.window)
        rows.append({"integrator": "explicit symplectic Euler", "contact_stiffness_N_per_m": kc,
                     "dt_s": dt, "wall_s_per_sim_s": wall / args.window, "max_penetration_m": pen,
                     "projected_wall_120s_process_s": wall / args.window * 120.0})
    for dt in (2e-3, 1e-2):
        wall, pen, x_imp = implicit_settle(params, args.window, dt)
        rows.append({"integrator": "implicit backward Euler (inertial)",
                     "contact_stiffness_N_per_m": params.solver.contact_stiffness,
                     "dt_s": dt, "wall_s_per_sim_s": wall / args.window, "max_penetration_m": pen,
                     "projected_wall_120s_process_s": wall / args.window * 120.0})
    # the process itself: quasi-static long steps
    simulation._SETTLED.clear()
    simulation.Simulation(params)          # settle once (cached), not part of the process
    plan = movement_plan(params, 4)
    res = run_scenario(params, plan)
    rows.append({"integrator": "implicit backward Euler (quasi-static process, movement 4)",
                 "contact_stiffness_N_per_m": params.solver.contact_stiffness,
                 "dt_s": params.solver.dt, "wall_s_per_sim_s": res.wall_time_s / 120.0,
                 "max_penetration_m": None, "projected_wall_120s_process_s": res.wall_time_s})
    # same physics? the explicit (stiff contact) and implicit settles after the window
    _, _, _, x_exp = explicit_settle(params, 1e7, args.window)
    _, _, x_imp = implicit_settle(params, args.window, 2e-3)
    out = {"machine": f"{platform.machine()} {platform.processor() or ''} python "
                      f"{platform.python_version()}",
           "window_s": args.window, "rows": rows,
           "explicit_vs_implicit_settle_max_diff_m": float(np.max(np.abs(x_exp - x_imp)))}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"settle window {args.window} s of the default cell; {out['machine']}")
    print(
        f"{'integrator':58s} {'K_c [N/m]':>9s} {'dt [s]':>9s} {'wall/sim':>9s} "
        f"{'max pen [m]':>11s} {'120 s [s]':>9s}")
    for r in rows:
        pen = "-" if r["max_penetration_m"] is None else f"{r['max_penetration_m']:.1e}"
        print(f"{r['integrator']:58s} {r['contact_stiffness_N_per_m']:9.0e} {r['dt_s']:9.1e} "
              f"{r['wall_s_per_sim_s']:9.3g} {pen:>11s} {r['projected_wall_120s_process_s']:9.3g}")
    print(f"explicit (K_c 1e7) vs implicit (dt 2e-3) positions after the window: "
          f"max difference {out['explicit_vs_implicit_settle_max_diff_m']:.2e} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
