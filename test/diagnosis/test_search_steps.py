"""A candidate's first point and its chord steps when a run fails (rheo_shaping.diagnosis.check;
no simulation: the runs are stubbed).  A linearised fit can land far out, where the model does
not run (a tool offset at its bounds pressing the sheet through the mould): the candidate is
then run halfway back to the baseline, not given up; a chord step whose runs fail is halved
next time, as one that does not lower J is."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from rheo_shaping.diagnosis import check as check_mod
from rheo_shaping.diagnosis.candidates import Explanation
from rheo_shaping.diagnosis.check import BACKTRACK, halfway, simulate_points
from rheo_shaping.diagnosis.evaluate import Outcome
from rheo_shaping.params.cell import CellParams

#: Beyond this tool offset [m] per axis the stubbed model does not run.
RUNS_WITHIN = 1.5e-3


def _stub_runs(seen: list):
    """A stand-in for :func:`check.simulate_points`: a point runs when its tool offset is within
    RUNS_WITHIN on both axes (J grows with the offset), else its runs fail."""
    def fake(points, ctx, base, *, m, first, kept=None):
        for c, u, vals in points:
            seen.append((np.array(u, float), vals))
            off = vals["tool_offset"]
            if max(abs(x) for x in off) > RUNS_WITHIN:
                if first:
                    c.checked, c.J, c.p = True, math.inf, 1.0
                continue
            c.checked, c.values, c.baseline_u = True, dict(vals), np.r_[u, 0.0]
            c.J = 1.0 + 1e3 * float(np.hypot(*off))
    return fake


def test_a_first_point_whose_runs_fail_is_run_halfway_back_to_the_baseline(monkeypatch):
    seen: list = []
    monkeypatch.setattr(check_mod, "simulate_points", _stub_runs(seen))
    base = SimpleNamespace(u_s=np.array([0.2, -0.4]))
    ctx = SimpleNamespace(n_s=2, sheet_lim=1.0, sheet_lo=-np.ones(2), sheet_hi=np.ones(2))
    c = Explanation(("tool_offset",), {"tool_offset": (-4e-3, -4e-3)}, 3.0, checked=False,
                    baseline_u=np.array([0.8, 0.6, 0.0]))      # the linearised step
    check_mod.check([c], ctx, base, m=1)
    # (-4, -4) mm and (-2, -2) mm fail, (-1, -1) mm runs: two halvings
    assert [v["tool_offset"] for _, v in seen] == [(-4e-3, -4e-3), (-2e-3, -2e-3),
                                                   (-1e-3, -1e-3)]
    assert math.isfinite(c.J) and c.checked
    assert c.values["tool_offset"] == pytest.approx((-1e-3, -1e-3))
    first = np.clip(base.u_s + np.array([0.8, 0.6]), -1.0, 1.0)
    assert seen[-1][0] == pytest.approx(base.u_s + 0.25 * (first - base.u_s))
    # a point that never runs stays failed after BACKTRACK halvings
    seen.clear()
    far = Explanation(("tool_offset",), {"tool_offset": (0.1, 0.0)}, 3.0,
                      baseline_u=np.zeros(3))
    check_mod.check([far], ctx, base, m=1)
    assert len(seen) == 1 + BACKTRACK and not math.isfinite(far.J)


def test_halfway_halves_each_effects_magnitude():
    assert halfway(("tool_offset",), {"tool_offset": (2e-3, -1e-3)}) == {
        "tool_offset": (1e-3, -5e-4)}
    # power_law's magnitude is 1 - n: n 0.45 -> 1 - 0.55 / 2
    assert halfway(("power_law",), {"power_law": (0.45,)})["power_law"][0] == pytest.approx(
        0.725)
    h = halfway(("bending", "mass_error"), {"bending": (1e-5,), "mass_error": (-0.4,)})
    assert h == {"bending": (5e-6,), "mass_error": (-0.2,)}


def test_a_chord_step_whose_runs_fail_is_halved_next_time():
    d = SimpleNamespace()
    ctx = SimpleNamespace(G=None, H=None, nf=1, fit_d=[d], data=[d],
                          params=lambda d, u: CellParams(),
                          run=lambda tasks: [Outcome(ok=False) for _ in tasks])
    c = Explanation(("tool_offset",), {"tool_offset": (5e-4, 0.0)}, 2.0, checked=True)
    simulate_points([(c, np.zeros(2), {"tool_offset": (9e-4, 0.0)})], ctx, None, m=1,
                    first=False, kept={})
    assert c.search.damp == 0.5 and c.J == 2.0
    assert c.values == {"tool_offset": (5e-4, 0.0)}
