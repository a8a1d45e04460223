"""The gap watch (issue 29): the model beside a running cell, its residuals per observable and
phase, OK / WARN / ERROR against a floor, a diagnosis of the run on a sustained WARN.
Imports :mod:`rheo_shaping.params`, :mod:`rheo_shaping.sheet`, :mod:`rheo_shaping.planning`,
:mod:`rheo_shaping.records`, :mod:`rheo_shaping.diagnosis`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'floor': ['ResidualFloor', 'ResidualFloorError', 'DEFAULT_FLOOR'],
    'watch': ['GapWatch', 'Status', 'signed_distance'],
    'feed': ['watch_record', 'Verdict', 'diagnose_record', 'DiagnosisJobs'],
    'queue': ['SampleQueue'],
    'session': ['WatchSession', 'Report'],
})
