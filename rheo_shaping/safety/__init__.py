"""Safety decisions without ROS: the abort budget (principle 4), stream
watchdogs, the monitor's decision core.  Imports params, sheet, planning.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'abort_budget': ['AbortBudget', 'abort_budget'],
    'watchdog': ['StallGuard', 'Freshness'],
    'acknowledge': ['Acknowledgements', 'MonitorLead'],
    'clock_guard': ['ClockGuard'],
    'command_gate': ['CommandGate', 'Publisher', 'ToolLimits'],
    'monitor': ['TensionMonitor'],
    'owners': ['StreamOwner', 'Trust'],
    'manager': ['Requests', 'cell_status'],
})
