"""Closed-loop shaping: the online estimate of the batch's material from the run's
samples, the re-plan of the rest of the movement from its pessimistic end, joined
jerk-limited to the running plan, and the offline closed loop against the sheet model (the
same loop against the dynamic world is the validation's:
:mod:`rheo_shaping_validation.world_loop`).  Imports :mod:`rheo_shaping.params`,
:mod:`rheo_shaping.sheet`, :mod:`rheo_shaping.planning` and :mod:`rheo_shaping.safety` (the
monitor's threshold).
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'observe': ['Sample', 'NoiseModel'],
    'estimator': ['Estimator', 'EstimatorParams', 'Estimate', 'EstimateStatus'],
    'join': ['ToolState', 'plan_from_state', 'splice'],
    'schedule': ['Choice', 'Schedule', 'fixed_schedule'],
    'settle': ['LinearSettle', 'material_cell'],
    'replan': ['replan', 'Replan', 'ReplanStatus', 'ReplanLimits', 'Prediction'],
    'loop': ['run_closed_loop', 'LoopConfig', 'LoopResult', 'monitor_threshold'],
    'online': ['OnlineShaper', 'OnlineConfig', 'OnlineStep', 'Reason'],
    'worker': ['ShaperProcess'],
    'streamed': ['StreamedLoop', 'Refresh'],
})
