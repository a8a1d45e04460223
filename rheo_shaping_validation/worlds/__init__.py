"""Benchmark worlds of another form than the sheet model (issue 26): independent simulators
of the same cell whose records the diagnosis is scored on.  ``dynamic``: a chain of masses
with inertia, soft contact with Coulomb friction, the sheet laid and released at t = 0, the
library's effects and effects of its own, and its own measurement model; ``forms``: the
variations of its form (issue 46), a family of worlds drawn per case.
Imports :mod:`rheo_shaping.params`, :mod:`rheo_shaping.records` (the ``Record`` type) and
:mod:`rheo_shaping.units`; nothing of :mod:`rheo_shaping.sheet`.
"""
from rheo_shaping._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'params': ['WorldNumerics', 'LayParams', 'WorldEffects', 'WORLD_EFFECTS',
               'WORLD_EFFECT_NAMES', 'draw_lay'],
    'dynamic': ['WorldRun', 'run_world', 'laid_shape', 'scenario_length'],
    'sensors': ['SensorParams', 'measure_world', 'world_record'],
    'verify': ['RunGap', 'run_gap'],
    'forms': ['Variation', 'FormParams', 'VariationRange', 'VARIATIONS', 'draw_form',
              'check_variations', 'thickness_profile'],
})
