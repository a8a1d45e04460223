"""The diagnosis benchmark (``rheo-shaping-validation diagnose-benchmark``): cases drawn in a
:class:`~.world.World` (:mod:`.cases`), each diagnosed on two records with a third held out,
scored against its truth (:mod:`.score`), run on an executor and resumable (:mod:`.run`,
:mod:`.checkpoint`).  docs/diagnosis.md, "Validation"."""
from rheo_shaping._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'world': ['World', 'FinerChain', 'DynamicWorld', 'WORLDS', 'TRUE_NUMERICS', 'check_world',
              'true_numerics', 'measure_chain'],
    'cases': ['make_case', 'base_cell', 'draw_value', 'NoCase', 'DRAWS', 'KINDS_PATTERN',
              'SENSOR_ERRORS'],
    'score': ['score_case', 'summarise', 'against_target', 'is_fraction', 'TARGETS',
              'NAMES_NOTHING', 'NAMES_NO_EFFECT'],
    'run': ['run_benchmark', 'library_for'],
    'checkpoint': ['append_partial', 'read_partial'],
})
