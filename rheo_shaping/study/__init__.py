"""The paper's study (Table 2, Figs. 18-19): the movements' runs, the d sweep and
its optimum (the choice of d itself is planning's: :mod:`rheo_shaping.planning.choose_d`),
the sag test.  Imports params, sheet, planning and
:mod:`rheo_shaping.parallel`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'reproduce': ['Study', 'reproduce'],
})
