"""Quality and safety figures (rheo_shaping.sheet.metrics): SF = F_break / F_max."""
from __future__ import annotations

import math

import pytest

from rheo_shaping.sheet.metrics import safety_factor


@pytest.mark.parametrize("F_max, sf", [(0.5, 2.08), (1.04, 1.0), (0.0, math.inf),
                                       (-1.0, math.inf), (math.nan, math.inf),
                                       (math.inf, 0.0)])
def test_safety_factor_is_F_break_over_F_max_and_inf_without_a_tension(F_max, sf):
    assert safety_factor(1.04, F_max) == pytest.approx(sf)
