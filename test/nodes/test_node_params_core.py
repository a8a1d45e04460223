"""The monitor node's default threshold is the core's abort budget (safety principle 4);
the ROS-free checks of the nodes' settings are in test/params/test_node_params.py."""
from __future__ import annotations

import pytest

from rheo_shaping.safety.abort_budget import abort_budget
from rheo_shaping.params.node_params import MonitorNodeParams
from rheo_shaping.params.schema import to_flat

from _support.cells import base_cell


def test_monitor_default_threshold_is_lesson_4_at_the_configured_speed(ros):
    """abort_ratio 0 (the default): F_abort = F_break - r (t_detect + t_stop) - 3 sigma with r
    the largest tension rate of movements 1-4 at the cell's speed, from the core, now."""
    from rclpy.parameter import Parameter
    from rheo_shaping.nodes.monitor import MonitorNode
    assert MonitorNodeParams().abort_ratio == 0.0
    cell = base_cell()
    overrides = [Parameter(k, value=v) for k, v in to_flat(cell).items()]
    monitor = ros.add(MonitorNode(context=ros.context, parameter_overrides=overrides))
    budget = abort_budget(cell, speed_factors=(1.0,), t_detect=MonitorNodeParams().detect_time,
                          sigma=MonitorNodeParams().noise_sigma)
    assert monitor.threshold == pytest.approx(budget.F_abort_max, rel=1e-9)
    assert monitor.threshold < cell.material.F_break
    print(budget.table())
