"""Tool motions: jerk-limited plans (ruckig), the paper's four movements,
stopping from any state, clearance of a plan; and the one way to run a
movement of a cell.  Imports :mod:`rheo_shaping.params` and
:mod:`rheo_shaping.sheet`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'limits': ['MotionLimits'],
    'plans': ['Plan', 'Waypoint', 'plan_waypoints'],
    'movement': ['run_movement', 'movement_plan'],
    'choose_d': ['best_d', 'run_d', 'd_values'],
    'scenarios': ['movement_scenario', 'scenario_plan'],
    'stopping': ['TrajectoryStreamer', 'stopping_time'],
})
