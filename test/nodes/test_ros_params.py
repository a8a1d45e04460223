"""ROS parameters from the schema: descriptors, refusal at start and at runtime."""
from __future__ import annotations

import subprocess

import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from rheo_shaping.params.node_params import (NODE_PARAMS, MonitorNodeParams,  # noqa: E402
                                             SimulatorNodeParams)
from rheo_shaping.nodes.monitor import MonitorNode  # noqa: E402
from rheo_shaping.nodes.ros_params import SchemaParameters  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.params.schema import ParameterError, iter_fields  # noqa: E402

from _support.ros import BIN  # noqa: E402


def test_every_node_setting_has_description_unit_and_range():
    for cls in NODE_PARAMS.values():
        for fi in iter_fields(cls):
            assert fi.spec.description, fi.name
            if fi.kind in (float, int):
                assert fi.spec.lo is not None and fi.spec.hi is not None, fi.name


def _schema_node(ros, overrides=(), groups=None, locked=True):
    node = ros.node("schema_test", parameter_overrides=list(overrides))
    return node, SchemaParameters(node,
                                  groups or {"cell": CellParams, "settings": MonitorNodeParams},
                                  locked=locked)


def test_descriptors_carry_description_unit_and_range(ros):
    node, params = _schema_node(ros)
    d = node.describe_parameter("material.k1")
    assert "spring k1" in d.description and "[N/m]" in d.description
    assert "(0, 1e+06]" in d.description
    assert d.floating_point_range[0].from_value == 0.0
    assert d.floating_point_range[0].to_value == 1e6
    n = node.describe_parameter("sheet.n_masses")
    assert n.integer_range[0].from_value == 1 and n.integer_range[0].to_value == 2000
    r = node.describe_parameter("abort_ratio")
    assert "F_break" in r.description and r.floating_point_range[0].to_value == 0.99
    assert r.description.endswith("; read-only while the node runs")
    assert not node.describe_parameter("diagnostics_period").description.endswith("runs")
    c2 = node.describe_parameter("material.c2")          # unbounded above: no ROS range
    assert not c2.floating_point_range and "inf" in c2.description
    assert params["cell"] == CellParams()
    assert params["settings"] == MonitorNodeParams()


def test_start_refuses_out_of_range_value_with_the_schema_message(ros):
    with pytest.raises(ParameterError) as exc:
        _schema_node(ros, [Parameter("abort_ratio", value=1.5)])
    text = str(exc.value)
    assert "abort_ratio" in text and "1.5" in text and "[0, 0.99]" in text


def test_start_refuses_open_bound_and_cross_field(ros):
    with pytest.raises(ParameterError, match=r"material.k1.*0\.0.*\(0, 1e\+06\]"):
        _schema_node(ros, [Parameter("material.k1", value=0.0)])
    with pytest.raises(ParameterError, match="top_bond_x"):
        _schema_node(ros, [Parameter("sheet.top_bond_x", value=-0.001)])


def test_start_refuses_unknown_cell_parameter(ros):
    with pytest.raises(ParameterError, match="unknown parameter 'material.k11'"):
        _schema_node(ros, [Parameter("material.k11", value=1.0)])


def test_integer_accepted_for_float_and_converted(ros):
    node, params = _schema_node(ros, [Parameter("movement.process_time", value=100),
                                      Parameter("movement.dwells", value=[0, 20])])
    assert params["cell"].movement.process_time == 100.0
    assert isinstance(params["cell"].movement.process_time, float)
    assert params["cell"].movement.dwells == (0.0, 20.0)


def test_runtime_set_parameters_refused_with_name_value_and_range(ros):
    """The schema's checks at runtime (an unlocked schema node: every parameter may change)."""
    node, params = _schema_node(ros, locked=False)
    [res] = node.set_parameters([Parameter("max_data_age", value=0.0)])    # open bound: schema
    assert not res.successful
    assert "max_data_age" in res.reason and "0.0" in res.reason and "(0, 60]" in res.reason
    [res] = node.set_parameters([Parameter("abort_ratio", value=2.0)])     # beyond: rclpy's range
    assert not res.successful
    assert "abort_ratio" in res.reason and "2.0" in res.reason and "0.99" in res.reason
    [res] = node.set_parameters([Parameter("tool.home", value=[0.1])])
    assert not res.successful and "tool.home" in res.reason and "2 values" in res.reason
    [res] = node.set_parameters([Parameter("sheet.top_bond_x", value=-0.001)])   # cross-field
    assert not res.successful and "fillet_radius" in res.reason
    assert params["settings"].abort_ratio == MonitorNodeParams().abort_ratio   # unchanged
    [res] = node.set_parameters([Parameter("abort_ratio", value=0.5)])
    assert res.successful
    assert params["settings"].abort_ratio == 0.5


#: What a rogue node set on the running monitor (each tore the sheet before the lock).
ROGUE_CHANGES = [("material.F_break", 100.0), ("abort_ratio", 0.9), ("abort_ratio", 0.0),
                 ("check_cell", False), ("max_data_age", 60.0), ("detect_time", 0.0),
                 ("max_tension_ratio", 1e6), ("acknowledge", False), ("movement.speed", 0.01)]


@pytest.mark.parametrize("name,value", ROGUE_CHANGES)
def test_a_running_monitor_refuses_every_safety_parameter_change(ros, name, value):
    node = ros.add(MonitorNode(context=ros.context,
                               parameter_overrides=[Parameter("abort_ratio", value=0.7)]))
    threshold = node.threshold
    [res] = node.set_parameters([Parameter(name, value=value)])
    assert not res.successful
    assert res.reason == (f"parameter '{name}' is read-only while monitor runs (the cell's "
                          f"safety rests on it): a change means a new cell, a restart or "
                          f"cleanup and configure through the lifecycle")
    assert node.threshold == threshold == pytest.approx(0.7 * CellParams().material.F_break)
    assert node.get_parameter(name).value != value


def test_a_running_monitor_takes_a_tunable_setting(ros):
    node = ros.add(MonitorNode(context=ros.context,
                               parameter_overrides=[Parameter("abort_ratio", value=0.7)]))
    [res] = node.set_parameters([Parameter("diagnostics_period", value=0.25)])
    assert res.successful and node.settings.diagnostics_period == 0.25
    [res] = node.set_parameters([Parameter("diagnostics_period", value=0.0)])   # still checked
    assert not res.successful and "diagnostics_period" in res.reason


@pytest.mark.parametrize("exe,arg,name", [
    ("monitor", "abort_ratio:=1.5", "abort_ratio"),
    ("monitor", "abort_ratio:=1.0", "abort_ratio"),              # a threshold at F_break
    ("monitor", "abort_ratio:=0.98", "expected at most 0.9"),    # beyond principle 4 here
    ("simulator", "monitor_timeout:=0.0", "monitor_timeout"),    # never: tore the sheet
    ("simulator", "real_time_factor:=-1.0", "real_time_factor"),
    ("planner", "control_rate:=0.0", "control_rate"),
])
def test_executable_refuses_bad_parameter_at_start(exe, arg, name):
    proc = subprocess.run([str(BIN / exe), "--ros-args", "-p", arg], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout
    assert name in proc.stdout and "expected" in proc.stdout, proc.stdout


def test_simulator_settings_defaults_are_consistent():
    s = SimulatorNodeParams()
    # lockstep waits never look stale
    assert s.command_timeout < MonitorNodeParams().max_data_age
    assert s.offered_deadline <= MonitorNodeParams().max_data_age    # QoS compatible


@pytest.mark.parametrize("exe", ["simulator", "planner", "monitor", "lifecycle_manager",
                                 "gap_watch", "monitor_managed"])
def test_a_params_file_nested_5000_deep_is_refused_by_name(exe, tmp_path):
    """Every executable exited with a RecursionError traceback on such a file."""
    deep = tmp_path / "deep.yaml"
    deep.write_text("/**:\n  ros__parameters:\n    x: " + "[" * 5000 + "]" * 5000 + "\n")
    proc = subprocess.run([str(BIN / exe), "--ros-args", "--params-file", str(deep)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=60)
    assert proc.returncode == 2, proc.stdout
    assert f"{deep}: nested too deep to read" in proc.stdout, proc.stdout
    assert "Traceback" not in proc.stdout
