"""Recorded runs: the record type, rosbag2 (MCAP) files with ``scenario.yaml``,
CSV import, and the measurement model that makes stand-ins from the simulator.
Imports :mod:`rheo_shaping.params`, :mod:`rheo_shaping.sheet`,
:mod:`rheo_shaping.planning`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'record': ['Record'],
    'bag': ['RecordError', 'read_record', 'write_record'],
    'csv_import': ['import_csv'],
    'measurement': ['MeasurementParams', 'synthesize_record'],
})
