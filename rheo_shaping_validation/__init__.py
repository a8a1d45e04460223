"""rheo_shaping's validation: what the product is measured with, kept out of what it ships
to run a cell (``rheo_shaping`` imports nothing from here; test/architecture holds it).

* :mod:`.worlds`: the dynamic world, a second simulator of another form than the sheet
  model (inertia, soft contact with Coulomb friction, the sheet laid and released, effects
  and sensors of its own), with the variations of its form;
* :mod:`.benchmark`: the diagnosis benchmark (``rheo-shaping-validation
  diagnose-benchmark``): cases from a :class:`~.benchmark.world.World` (the sheet model on
  finer numerics, or the dynamic world), diagnosed and scored;
* :mod:`.gapwatch_campaign`: the gap watch's acceptance cases (benchmarks/gapwatch_*.py);
* :mod:`.world_loop`: the closed loop run against the dynamic world
  (benchmarks/closed_loop_campaign.py).

Imports :mod:`rheo_shaping` (its params, sheet, planning, records, diagnosis, gapwatch,
adaptive and cli helpers); no ROS.
"""
from rheo_shaping._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'benchmark.world': ['World', 'FinerChain', 'DynamicWorld', 'WORLDS'],
    'benchmark.cases': ['make_case', 'base_cell', 'NoCase'],
    'benchmark.run': ['run_benchmark'],
    'cli': ['main'],
})
