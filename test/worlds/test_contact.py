"""The dynamic world's contact against Coulomb's law (rheo_shaping_validation.worlds.kernel): a
flat tool (a 20 x 10 mm rounded rectangle) pressed onto a strip lying on the workplane and slid
along it.  While it slides the force on the tool leans back by exactly mu_tool
(F_x / F_z = -mu), the strip stuck to the workplane (mu_mould 1.2); without friction there
is no drag; the normal force is the penalty law's."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rheo_shaping_validation.worlds import kernel as K

R_SPHERE = 2e-3          # m, half the sheet's thickness
HALF_W, HALF_H, CORNER = 10e-3, 5e-3, 1e-3    # m, the tool
PITCH = 1.65e-3          # m
N = 40
PRESS = 5e-6             # m, how far the disc's path goes into the strip's top


def slide(mu_tool: float, mu_mould: float = 1.2, soft_tool: float = 0.0, soft_mould: float = 0.0):
    x = np.c_[PITCH * np.arange(1, N + 1), np.full(N, R_SPHERE)]
    anchors = np.array([[0.0, R_SPHERE], [PITCH * (N + 1), R_SPHERE]])
    L0 = np.full(N + 1, PITCH)
    scale = 0.1 / PITCH
    k1, c1, c2 = np.full(N + 1, 95.0 * scale), np.zeros(N + 1), np.full(N + 1, 1.3e3 * scale)
    mass = np.full(N, 0.3125 * PITCH)
    par = np.zeros(K.N_PAR)
    par[K.I_GRAV] = 9.81
    par[K.I_KC] = 5e7 * PITCH
    par[K.I_CN] = 2 * 0.5 * math.sqrt(par[K.I_KC] * mass[0])
    par[K.I_KT] = par[K.I_KC]
    par[K.I_MU_MOULD], par[K.I_MU_TOOL] = mu_mould, mu_tool
    par[K.I_AIR] = 3.0
    par[K.I_CAKE_H], par[K.I_FILLET] = -1.0, 0.01          # the cake out of the way
    par[K.I_RADIUS], par[K.I_TOOL_R] = R_SPHERE, CORNER
    par[K.I_PL_N], par[K.I_PL_REF] = 1.0, 0.5
    par[K.I_SOFT_TOOL], par[K.I_SOFT_MOULD] = soft_tool, soft_mould    # 0: not softened
    a, b = HALF_W - CORNER, HALF_H - CORNER
    verts = np.array([[-a, -b], [a, -b], [a, b], [-a, b]])
    t = np.linspace(0.0, 20.0, 2001)
    z_top, z_press = 2 * R_SPHERE + HALF_H + 1e-3, 2 * R_SPHERE + HALF_H - PRESS
    zt = np.interp(t, [0.0, 2.0, 20.0], [z_top, z_press, z_press])
    xt = np.interp(t, [0.0, 3.0, 18.0, 20.0], [0.02, 0.02, 0.035, 0.035])
    hs = np.full(20000, 1e-3)
    keep = np.zeros(hs.size, dtype=bool)
    keep[19::20] = True
    out = K.run_chain(x, np.zeros_like(x), anchors, L0, k1, c1, c2, mass, par, verts, t,
                      np.c_[xt, zt], hs, keep, np.zeros(N + 1), np.zeros(N + 1))
    ts, xs, _F, ftool, _p, _fm, status, unconverged = out
    assert status == 0
    return ts, xs, ftool, par, unconverged


@pytest.mark.parametrize("mu", [0.3, 0.6])
def test_a_sliding_tool_is_dragged_by_mu_times_the_normal_force(mu):
    t, _x, f, _par, unconverged = slide(mu)
    assert unconverged <= 20      # of 20000 steps: a contact set that cycles takes the last solve
    sliding = (t > 5.0) & (t < 17.0)                 # the tool moves at 1 mm/s along x
    assert np.all(f[sliding, 1] > 0.1)                # pressed: the sheet pushes it up
    ratio = -f[sliding, 0] / f[sliding, 1]
    assert np.abs(ratio - mu).max() < 0.02 * mu


def test_no_friction_no_drag_and_the_penetration_is_the_penalty_law():
    t, x, f, par, unconverged = slide(0.0)
    assert unconverged <= 20
    sliding = (t > 5.0) & (t < 17.0)
    # no drag but the rounded edges' push on the masses they pass, front and back: on
    # average nothing (against 0.3 of the normal force with mu_tool = 0.3)
    assert abs(f[sliding, 0].mean()) < 1e-3 * f[sliding, 1].mean()
    # the masses under the flat face: two penalty springs in series take PRESS, each
    # carrying kc PRESS / 2 (plus a little of the strip's weight)
    under = np.abs(x[0, :, 0] - 0.027) < HALF_W - CORNER - PITCH
    k = int(np.searchsorted(t, 10.0))
    xs_k = x[k, :, 0]
    n_under = int(np.sum(np.abs(xs_k - (0.02 + (t[k] - 3.0) * 1e-3)) < HALF_W - CORNER))
    per_mass = f[k, 1] / n_under
    assert per_mass == pytest.approx(par[K.I_KC] * PRESS / 2, rel=0.05)
    assert under.any()


@pytest.mark.parametrize("soft_tool, soft_mould", [(3.0, 0.0), (1.0, 4.0), (2.5, 1.5)])
def test_a_soft_tool_or_mould_is_the_penalty_law_over_its_factor(soft_tool, soft_mould):
    """Issue 46's soft contacts: the tool's and the workplane's penalty springs divided by
    their factors (0 reads as 1) in series take PRESS, the workplane's the mass's weight W
    besides: (PRESS - W f_mould / kc) kc / (f_tool + f_mould) per mass under the flat face."""
    t, x, f, par, unconverged = slide(0.0, soft_tool=soft_tool, soft_mould=soft_mould)
    assert unconverged <= 20
    k = int(np.searchsorted(t, 10.0))
    n_under = int(np.sum(np.abs(x[k, :, 0] - (0.02 + (t[k] - 3.0) * 1e-3)) < HALF_W - CORNER))
    fm = soft_mould if soft_mould > 0 else 1.0
    w = 0.3125 * PITCH * par[K.I_GRAV]
    kc = par[K.I_KC]
    assert f[k, 1] / n_under == pytest.approx((PRESS - w * fm / kc) * kc / (soft_tool + fm),
                                              rel=0.02)
