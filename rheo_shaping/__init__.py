"""rheo_shaping: robotic shaping of thin rheological sheets over a mould.

The entry points a user scripts against, imported on first use (``import
rheo_shaping`` loads neither numba nor scipy)::

    import rheo_shaping as rs
    cell = rs.load_cell("my_cell.yaml")           # a params YAML -> CellParams
    run = rs.run_movement(cell, 4, speed=2e-3)    # plan + simulate -> RunResult
    print(run.summary())                          # F_max [N], SF, delta [m], ...
    fit = rs.identify_paper(residuals, tensile)   # the paper's identification (Sec. 3.4)
    report = rs.diagnose([rs.read_record("run-01")])  # the sim-to-real diagnosis

The core (params, material, identification, sheet, planning, records, study,
safety, diagnosis) imports no ROS; the ROS 2 nodes live in
:mod:`rheo_shaping.nodes`.  docs/architecture.md maps the subpackages.
"""
from ._lazy import lazy_api

__version__ = "0.1.0"

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'params.config': ['load_cell', 'dump_cell'],
    'params.cell': ['CellParams'],
    'planning.movement': ['run_movement', 'movement_plan'],
    'identification.paper_method': ['identify_paper'],
    'identification.model_choice': ['identify_joint'],
    'records.bag': ['read_record'],
    'diagnosis.engine': ['diagnose'],
})
__all__ = ['__version__', *__all__]
