"""Parameters of a shaping cell and of its nodes: the declarative schema (units,
ranges), the frozen dataclasses, the params YAML files and the input checks.
Imports nothing else of the package.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'cell': ['CellParams', 'MaterialParams', 'SheetParams', 'CakeParams', 'ToolParams',
             'MovementParams', 'SolverParams', 'EffectsParams'],
    'schema': ['ParameterError', 'param'],
    'config': ['ConfigError', 'load_cell', 'dump_cell'],
    'node_params': ['SimulatorNodeParams', 'PlannerNodeParams', 'MonitorNodeParams'],
    'wire': ['WireError', 'load_json', 'read_fields', 'Field'],
})
