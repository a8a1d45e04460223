"""The paper's study (Table 2, Figs. 18-19): the movements' runs, the d sweep and
its optimum, the sag test.  Imports params, sheet, planning and
:mod:`rheo_shaping.parallel`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'reproduce': ['Study', 'reproduce'],
    'optimise': ['best_d', 'run_d'],
})
