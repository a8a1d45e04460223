"""The sim-to-real diagnosis: where the model parts from recorded runs, which effect causes it,
how far the gap shrinks (docs/diagnosis.md).

    from rheo_shaping.diagnosis import diagnose, Verdict
    d = diagnose(fit_records, holdout_records)     # defaults: DEFAULTS, as the command's
    if d.verdict is Verdict.EFFECT:
        print(d.named, d.verdict_fit.values, d.floor.verdict)
    json.dumps(d.to_json())                         # what ``diagnose --json`` prints

Imports :mod:`rheo_shaping.params`, :mod:`rheo_shaping.sheet`, :mod:`rheo_shaping.planning`,
:mod:`rheo_shaping.records` and :mod:`rheo_shaping.parallel`; no ROS.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'engine': ['diagnose'],
    'result': ['Diagnosis', 'Verdict'],
    'options': ['Options', 'DEFAULTS', 'InitialMode', 'FloorKind', 'BaselineMode'],
    'figures': ['Noise', 'GapFigures', 'GapGroups', 'Remainder', 'FloorReport'],
    'naming': ['Naming'],
    'floor': ['FloorError'],
    'candidates': ['Explanation'],
})
