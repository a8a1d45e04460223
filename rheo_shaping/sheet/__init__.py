"""The sheet over the mould (paper Sec. 4.1): geometry of cake, workplane and tool,
the chain of lumped masses and its compiled step, a tool path's simulation,
metrics, the effects library, closed-form references and plots.
Imports :mod:`rheo_shaping.params`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'geometry': ['Cake', 'Workplane'],
    'tools': ['tool_shape'],
    'simulation': ['RunResult', 'run_scenario'],
    'paths': ['PolylinePath', 'ToolPath'],
    'chain': ['SheetModel', 'SheetState'],
    'effects': ['EFFECTS', 'EFFECT_NAMES'],
})
