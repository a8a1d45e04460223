#!/usr/bin/env python3
"""The bending stiffness's tool-force response in the dynamic world against the sheet model's:
the default cell at 63 masses, movements 1-3 over 120 s, EI 0, 4.2e-6 and 8.4e-6 N m^2; prints
per movement and EI the RMS of (with - without) tool force [N] in each, their ratio, and the
change of F_max [N].  A ratio of 1 says the world's bending and the model's act alike on the
plain world (no form variation), so a bending fitted at half its size on a varied world is
the form's doing, not the scale's (docs/diagnosis.md, "Where it stands").

    python benchmarks/bending_response.py
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.simulation import run_scenario
from rheo_shaping_validation.worlds.dynamic import run_world

EIS = (4.2e-6, 8.4e-6)        # N m^2


def rms(d: np.ndarray) -> float:
    return float(np.sqrt((d ** 2).sum(axis=1).mean()))


def main() -> None:
    for mv in (1, 2, 3):
        p = CellParams()
        p = replace(p, movement=replace(p.movement, number=mv, process_time=120.0),
                    sheet=replace(p.sheet, n_masses=63))
        path = movement_plan(p)
        runs = {}
        for EI in (0.0,) + EIS:
            q = replace(p, effects=replace(p.effects, bending=EI))
            runs[EI] = (run_world(q, path), run_scenario(q, path))
        w0, m0 = runs[0.0]
        for EI in EIS:
            w, m = runs[EI]
            on_grid = [np.column_stack([np.interp(w.t, r.t, r.tool_force[:, i]) for i in (0, 1)])
                       for r in (m, m0)]
            dw, dm = rms(w.tool_force - w0.tool_force), rms(on_grid[0] - on_grid[1])
            print(f"movement {mv}, EI {EI:.1e} N m^2: world dF {dw:.4f} N, model dF {dm:.4f} N, "
                  f"ratio {dw / dm:.2f}; dF_max world {w.F_max - w0.F_max:.4f} N, "
                  f"model {m.F_max - m0.F_max:.4f} N")


if __name__ == "__main__":
    main()
