#!/usr/bin/env python3
"""Convergence of the lumped elastic chain to Irvine's elastic catenary.

For N = 10, 20, 50, 100, 200 masses (``rheo_shaping.sheet.catenary.discretise_cable``)
the exact chain equilibrium is compared with Irvine's closed form:

* ``err_node`` [m]: largest distance between a mass and the cable point with
  the same Lagrangian coordinate s (the stricter measure);
* ``err_curve`` [m]: largest distance from a mass to Irvine's curve (nearest
  point on it, any s).

``ratio`` is the previous row's error over this row's; second-order
convergence gives ((N + 1) / (N_prev + 1))^2: 3.64, 5.90, 3.92, 3.96.

Defaults are the paper's fondant strip: EA = k1 * 0.1 m = 9.5 N, w = 0.3 kg/m * 9.81,
L0 = 0.15 m, span 0.10 m, height difference -0.08 m.

A second table runs the simulator itself on the same chains: a
``SheetModel`` with purely elastic links (c1 = 0, c2 = inf, k_i = EA/L_i), no
obstacles, started from the straight chord at rest (links slack) and stepped
quasi-statically (``dynamic=False``, steps of ``--sim-dt`` = 1e3 s, until a
step moves no mass by more than 1e-10 m; force tolerance 1e-11 N,
``max_newton`` 500 because the Newton iteration from the slack start needs
more than the default 50 iterations at N >= 100).  It prints

* ``err_exact`` [m]: largest distance of a settled mass from the exact discrete
  equilibrium (``analytic.solve_elastic_chain``) -- the simulator solves the
  discrete problem (round-off level);
* ``err_irvine`` [m]: largest distance from Irvine's cable point with the same
  s, and its ratio to the previous row -- the simulator converges to Irvine's
  elastic catenary at second order as N grows;
* ``dT_exact`` [N]: largest link tension error against the exact chain.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

try:
    from rheo_shaping.sheet.catenary import discretise_cable, solve_irvine
except ImportError:                                   # run from a source tree without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from rheo_shaping.sheet.catenary import discretise_cable, solve_irvine

G = 9.81


def curve_distance(cab, p: np.ndarray, s_guess: float, window: float) -> float:
    """Distance [m] from point p to Irvine's curve, searching s near s_guess."""
    def d2(s: float) -> float:
        x, z = cab.position(s)
        return float((x - p[0]) ** 2 + (z - p[1]) ** 2)
    lo, hi = max(0.0, s_guess - window), min(cab.L0, s_guess + window)
    res = minimize_scalar(d2, bounds=(lo, hi), method="bounded", options={"xatol": 1e-14})
    return math.sqrt(min(res.fun, d2(s_guess)))


def run(span: float, height_difference: float, length: float, ea: float, w: float,
        ns: list[int], curve: bool = True) -> dict:
    """Error table as a dict (SI units)."""
    cab = solve_irvine(span, height_difference, length, ea, w)
    rows = []
    prev = None
    for n in ns:
        lumped = discretise_cable(span, height_difference, length, ea, w, n, G)
        t0 = time.perf_counter()
        sol = lumped.solve()
        dt = time.perf_counter() - t0
        x, z = cab.position(lumped.s_nodes)
        err_node = float(np.hypot(sol.positions[:, 0] - x, sol.positions[:, 1] - z).max())
        row = {"N": n, "err_node_m": err_node,
               "ratio_node": (prev["err_node_m"] / err_node) if prev else None,
               "H_chain_N": sol.H, "mismatch_m": sol.mismatch, "iterations": sol.iterations,
               "solve_time_s": dt}
        if curve:
            seg = length / (n + 1)
            err_curve = max(curve_distance(cab, p, s, 2 * seg)
                            for p, s in zip(sol.positions, lumped.s_nodes))
            row["err_curve_m"] = err_curve
            row["ratio_curve"] = (prev["err_curve_m"] / err_curve) if prev else None
        rows.append(row)
        prev = row
    return {"span_m": span, "height_difference_m": height_difference,
            "unstretched_length_m": length,
            "EA_N": ea, "weight_per_length_N_per_m": w, "H_irvine_N": cab.H, "V_irvine_N": cab.V,
            "rows": rows}


def simulate(span: float, height_difference: float, length: float, ea: float, w: float,
             ns: list[int], dt: float = 1e3, force_tol: float = 1e-11, max_newton: int = 500,
             max_steps: int = 6) -> dict:
    """The simulator's settled elastic chains against the exact chain and Irvine (SI units)."""
    from rheo_shaping.sheet.chain import ChainConstants, SheetModel

    cab = solve_irvine(span, height_difference, length, ea, w)
    rows = []
    prev = None
    for n in ns:
        lumped = discretise_cable(span, height_difference, length, ea, w, n, G)
        exact = lumped.solve()
        c = ChainConstants(anchor_top=lumped.anchor_a, anchor_bottom=lumped.anchor_b,
                           rest_length=lumped.rest_lengths, k1=lumped.stiffness, c1=np.zeros(
                               n + 1),
                           c2=np.full(n + 1, np.inf), mass=lumped.masses, radius=1e-3, gravity=G)
        model = SheetModel(c, [], force_tol=force_tol, max_newton=max_newton)
        s = np.linspace(0.0, 1.0, n + 2)[1:-1, None]
        state = model.initial_state(c.anchor_top + s * (c.anchor_bottom - c.anchor_top))
        t0 = time.perf_counter()
        iterations, steps = 0, 0
        for steps in range(1, max_steps + 1):
            before = state.x
            state = model.step(state, dt, dynamic=False)
            iterations += state.newton_iterations
            if np.max(np.abs(state.x - before)) < 1e-10:
                break
        wall = time.perf_counter() - t0
        x, z = cab.position(lumped.s_nodes)
        err_exact = float(np.hypot(*(state.x - exact.positions).T).max())
        err_irvine = float(np.hypot(state.x[:, 0] - x, state.x[:, 1] - z).max())
        row = {"N": n, "err_exact_m": err_exact, "err_irvine_m": err_irvine,
               "ratio_irvine": (prev["err_irvine_m"] / err_irvine) if prev else None,
               "dT_exact_N": float(np.abs(state.tension - exact.tensions).max()),
               "steps": steps, "newton_iterations": iterations, "wall_s": wall}
        rows.append(row)
        prev = row
    return {"dt_s": dt, "force_tol_N": force_tol, "max_newton": max_newton, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="Prints max node error [m] and ratio to the previous N.")
    ap.add_argument("--span", type=float, default=0.10,
                    help="horizontal support distance [m] (default 0.10)")
    ap.add_argument("--height-difference", type=float, default=-0.08,
                    help="z of the second support minus z of the first [m] (default -0.08)")
    ap.add_argument("--length", type=float, default=0.15,
                    help="unstretched cable length L0 [m] (default 0.15)")
    ap.add_argument("--EA", type=float, default=9.5,
                    help="axial stiffness [N] (default 9.5 = 95 N/m * 0.1 m)")
    ap.add_argument("--mass-per-length", type=float, default=0.3, help="[kg/m] (default 0.3)")
    ap.add_argument("--n", type=int, nargs="+",
                    default=[10, 20, 50, 100, 200], help="numbers of masses")
    ap.add_argument("--no-curve", action="store_true",
                    help="skip the nearest-point distance to the curve")
    ap.add_argument("--no-simulator", action="store_true",
                    help="skip the second table (the simulator's settled chain)")
    ap.add_argument("--sim-dt", type=float, default=1e3,
                    help="quasi-static step of the simulator [s] (default 1e3)")
    ap.add_argument("--json", action="store_true",
                    help="print one JSON object instead of the table")
    args = ap.parse_args(argv)
    try:
        out = run(args.span, args.height_difference, args.length, args.EA,
                  args.mass_per_length * G,
                  args.n, curve=not args.no_curve)
        if not args.no_simulator:
            out["simulator"] = simulate(args.span, args.height_difference, args.length, args.EA,
                                        args.mass_per_length * G, args.n, dt=args.sim_dt)
    except (ValueError, RuntimeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"Irvine: span {out['span_m']} m, dz {out['height_difference_m']} m, L0 "
          f"{out['unstretched_length_m']} m, "
          f"EA {out['EA_N']} N, w {out['weight_per_length_N_per_m']:.4g} N/m -> "
          f"H = {out['H_irvine_N']:.6g} N, V = {out['V_irvine_N']:.6g} N")
    head = f"{'N':>5} {'err_node [m]':>13} {'ratio':>6}"
    if not args.no_curve:
        head += f" {'err_curve [m]':>14} {'ratio':>6}"
    print(head + f" {'mismatch [m]':>13} {'iters':>5}")
    fmt = lambda r: f"{r:6.2f}" if r else f"{'-':>6}"  # noqa: E731
    for r in out["rows"]:
        line = f"{r['N']:>5} {r['err_node_m']:13.4e} {fmt(r['ratio_node'])}"
        if not args.no_curve:
            line += f" {r['err_curve_m']:14.4e} {fmt(r['ratio_curve'])}"
        print(line + f" {r['mismatch_m']:13.1e} {r['iterations']:>5}")
    if "simulator" in out:
        sim = out["simulator"]
        print("\nsimulator (SheetModel, c2 = inf, no obstacles; straight start, quasi-static "
              "steps of "
              f"{sim['dt_s']:g} s, force tol {sim['force_tol_N']:g} N):")
        print(f"{'N':>5} {'err_exact [m]':>13} {'dT_exact [N]':>12} {'err_irvine [m]':>14} "
              f"{'ratio':>6} "
              f"{'steps':>5} {'newton':>6} {'wall [s]':>8}")
        for r in sim["rows"]:
            print(f"{r['N']:>5} {r['err_exact_m']:13.2e} {r['dT_exact_N']:12.2e} "
                  f"{r['err_irvine_m']:14.4e} "
                  f"{fmt(r['ratio_irvine'])} {r['steps']:>5} {r['newton_iterations']:>6} "
                  f"{r['wall_s']:8.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
