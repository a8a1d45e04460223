"""The dynamic world's link law (rheo_shaping_validation.worlds.kernel: backward Euler of
paper Eq. 2)
against the paper's closed forms through one link: Eq. 5 (a pull at constant speed) and
Eq. 7-8 (creep under a constant force), Maxwell and with a Kelvin-Voigt c1."""
from __future__ import annotations

import numpy as np
import pytest

from rheo_shaping.material.closed_forms import creep_elongation, tensile_force
from rheo_shaping.material.three_element import ThreeElement
from rheo_shaping_validation.worlds.kernel import link_affine, link_update

MAXWELL = ThreeElement(k1=95.0, c1=0.0, c2=1.30e3)          # the paper's fondant (0.1 m)
KELVIN = ThreeElement(k1=95.0, c1=800.0, c2=1.30e3)         # with kelvin_c1 = 800 N s/m


def pull(m: ThreeElement, speed: float, h: float, t_end: float):
    """Force [N] of one link pulled at ``speed`` [m/s] from rest, steps of ``h`` [s]."""
    e1 = p = 0.0
    n = int(round(t_end / h))
    t = h * np.arange(1, n + 1)
    F = np.empty(n)
    for k in range(n):
        D = speed * t[k] - (e1 + p)              # end length beyond the free length
        e1, p, F[k] = link_update(m.k1, m.c1, m.c2, e1, p, D, h)
    return t, F


def creep(m: ThreeElement, force: float, h: float, t_end: float):
    """Elongation [m] of one link under ``force`` [N] from t = 0 (the affine law solved for
    the end length each step)."""
    e1 = p = 0.0
    n = int(round(t_end / h))
    t = h * np.arange(1, n + 1)
    x = np.empty(n)
    for k in range(n):
        A, S = link_affine(m.k1, m.c1, m.c2, e1, h)
        e1, p, F = link_update(m.k1, m.c1, m.c2, e1, p, (force - A) / S, h)
        assert F == pytest.approx(force, rel=1e-9)   # round-off of c1/h ~ 1e6 k1
        x[k] = e1 + p
    return t, x


@pytest.mark.parametrize("m", [MAXWELL, KELVIN], ids=["maxwell", "kelvin"])
def test_constant_speed_pull_is_eq5(m):
    """Eq. 5 at the world's step (1 ms) to 1e-4 of c2 v, first order in the step."""
    v = 1e-3
    errs = []
    for h in (1e-3, 5e-4):
        t, F = pull(m, v, h, 60.0)
        errs.append(np.abs(F - tensile_force(m, t, v)).max() / (m.c2 * v))
    assert errs[0] < 1e-4
    assert 1.8 < errs[0] / errs[1] < 2.2            # first order: half the step, half the error


def test_maxwell_creep_is_eq7_8_exactly():
    """A Maxwell link under a constant force creeps as Eq. 7-8 at any step (to round-off)."""
    for h in (1e-3, 0.1):
        t, x = creep(MAXWELL, 0.5, h, 30.0)
        ref = creep_elongation(MAXWELL, t, 0.5)
        assert np.abs(x - ref).max() < 1e-12 * ref.max()


def test_kelvin_creep_is_eq7_8_first_order():
    """With c1 > 0 the creep follows Eq. 7-8 to 1e-4 of its final elongation at 1 ms, first
    order in the step."""
    errs = []
    for h in (1e-3, 5e-4):
        t, x = creep(KELVIN, 0.5, h, 30.0)
        ref = creep_elongation(KELVIN, t, 0.5)
        errs.append(np.abs(x - ref).max() / ref[-1])
    assert errs[0] < 1e-4
    assert 1.8 < errs[0] / errs[1] < 2.2


def test_slack_link_carries_nothing_and_does_not_flow():
    """Shorter than its free length: no force, no plastic flow, the Kelvin part relaxes as
    c1 de1/dt = -k1 e1 (backward Euler)."""
    m = KELVIN
    e1, p, F = link_update(m.k1, m.c1, m.c2, 1e-3, 2e-3, -5e-3, 0.01)
    assert F == 0.0 and p == 2e-3
    assert e1 == pytest.approx(1e-3 * m.c1 / (m.c1 + m.k1 * 0.01))
    e1, p, F = link_update(MAXWELL.k1, 0.0, MAXWELL.c2, 1e-3, 2e-3, -5e-3, 0.01)
    assert (e1, p, F) == (0.0, 2e-3, 0.0)
