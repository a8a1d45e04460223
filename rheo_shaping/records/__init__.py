"""Recorded runs: the record type, rosbag2 (MCAP) files with ``scenario.yaml``,
CSV import, and the measurement model (what a camera, a load cell and the robot's pose
report of a run; :func:`rheo_shaping.planning.movement.synthesize_record` makes stand-ins
with it).  Imports :mod:`rheo_shaping.params`, :mod:`rheo_shaping.sheet`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'record': ['Record'],
    'bag': ['RecordError', 'read_record', 'write_record'],
    'csv_import': ['import_csv'],
    'measurement': ['MeasurementParams', 'measure'],
})
