"""Params files: one rule (rcl's) for the core and the nodes; ``-p`` beats the file.

* The core's loader (rheo_shaping.params.config) refuses exactly the files ``rclpy.init``
  refuses, checked here against the real rcl on each case.
* A node executable given a file the core refuses exits with code 2 and the core's
  message (the one ``rheo-shaping simulate`` prints), never a traceback.
* ``<node> --ros-args --params-file config/cell.yaml -p NAME:=VALUE`` reads back
  VALUE over the node's own section, for every node (issue 15); node sections keyed
  ``/**/<node>`` apply in a namespace too.
"""
from __future__ import annotations

import subprocess

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.context import Context  # noqa: E402

from rheo_shaping.params.config import ConfigError, check_params_file  # noqa: E402

from _support.ros import BIN, REPO  # noqa: E402

CELL_YAML = REPO / "config" / "cell.yaml"

#: name -> (file text, rcl accepts it)
RCL_CASES = {
    "no_ros_parameters": ("material:\n  k1: 95.0\n", False),
    "node_without_ros_parameters": ("/**:\n  material:\n    k1: 95.0\n", False),
    "mixed_float_int_list": ("/**:\n  ros__parameters:\n    tool:\n      home: [0.03, 1]\n",
                             False),
    "mixed_float_str_list": ("/**:\n  ros__parameters:\n    a: [1.0, x]\n", False),
    "nested_list": ("/**:\n  ros__parameters:\n    a: [[1.0], [2.0]]\n", False),
    "top_level_list": ("- a\n- b\n", False),
    "ros_parameters_list": ("/**:\n  ros__parameters: [1, 2]\n", False),
    "ros_parameters_scalar": ("/**:\n  ros__parameters: 3\n", False),
    "node_scalar": ("/**: 3\n", False),
    "key_beside_ros_parameters": ("/**:\n  ros__parameters:\n    a: 1\n  other: 2\n", False),
    "two_documents": ("/**:\n  ros__parameters:\n    a: 1\n---\nb: 2\n", False),
    "empty_node": ("/**:\n", False),
    "top_level_anchor": ("x: &x 1.0\n/**:\n  ros__parameters:\n    a: *x\n", False),
    "float_list": ("/**:\n  ros__parameters:\n    tool:\n      home: [0.03, 0.05]\n", True),
    "int_list": ("/**:\n  ros__parameters:\n    a: [1, 2]\n", True),
    "bool_list": ("/**:\n  ros__parameters:\n    a: [true, false]\n", True),
    "deep": ("/**:\n  ros__parameters:\n    a:\n      b:\n        c: 1\n", True),
    "wildcard_node": ("/**/planner:\n  ros__parameters:\n    control_rate: 20.0\n", True),
    "nested_namespace": ("cell2:\n  planner:\n    ros__parameters:\n      control_rate: 20.0\n",
                         True),
    "empty_file": ("", True),
    "empty_ros_parameters": ("/**:\n  ros__parameters: {}\n", True),
}


def _rcl_accepts(path) -> bool:
    context = Context()
    try:
        rclpy.init(args=["x", "--ros-args", "--params-file", str(path)], context=context)
    except Exception:     # noqa: BLE001  (rclpy raises _rclpy.RCLError)
        return False
    rclpy.try_shutdown(context=context)
    return True


@pytest.mark.parametrize("case", sorted(RCL_CASES))
def test_core_refuses_exactly_what_rcl_refuses(tmp_path, case):
    text, accepted = RCL_CASES[case]
    path = tmp_path / f"{case}.yaml"
    path.write_text(text)
    assert _rcl_accepts(path) is accepted, "the case's expectation is rcl's own verdict"
    if accepted:
        check_params_file(path)
    else:
        with pytest.raises(ConfigError) as info:
            check_params_file(path)
        assert str(path) in str(info.value)


#: Files the core and every node refuse, with a fragment of the message (key, value,
#: what was expected).
BAD_FILES = {
    "no_ros_parameters": ("material:\n  k1: 95.0\n", ["'material'", "ros__parameters"]),
    "mixed_list": ("/**:\n  ros__parameters:\n    tool:\n      home: [0.03, 1]\n",
                   ["'tool.home'", "[0.03, 1]", "one type", "1.0"]),
    "cell_in_node_section": ("/**/planner:\n  ros__parameters:\n    movement:\n"
                             "      number: 2\n",
                             ["'/**/planner'", "'movement.number'", "= 2", "'/**' section"]),
    "bad_cell_value": ("/**:\n  ros__parameters:\n    material: {k1: -1.0}\n",
                       ["material.k1", "-1.0", "(0, 1e+06]"]),
    "bad_node_value": ("/**/monitor:\n  ros__parameters:\n    abort_ratio: 1.5\n",
                       ["abort_ratio", "1.5", "[0, 0.99]"]),
}


def _core_message(path) -> str:
    proc = subprocess.run([str(BIN / "rheo-shaping"), "simulate", "--params", str(path)],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    return proc.stderr.strip().split("error: ", 1)[1]


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_every_node_refuses_a_bad_file_with_the_core_message_and_no_traceback(tmp_path, case):
    text, fragments = BAD_FILES[case]
    path = tmp_path / f"{case}.yaml"
    path.write_text(text)
    message = _core_message(path)
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    for node in ("simulator", "planner", "monitor"):
        proc = subprocess.run([str(BIN / node), "--ros-args", "--params-file", str(path)],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              timeout=120)
        assert proc.returncode == 2, (node, proc.stdout)
        assert "Traceback" not in proc.stdout, (node, proc.stdout)
        assert message in proc.stdout, (node, message, proc.stdout)


# -- -p beats the file -------------------------------------------------------------------
def _get_parameters(ros, node_fqn: str, names: list[str], timeout: float = 60.0) -> dict:
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    from rheo_shaping.nodes.services import query
    client_node = ros.node("params_reader_" + node_fqn.strip("/").replace("/", "_"))
    client = client_node.create_client(GetParameters, f"{node_fqn}/get_parameters")
    ros.spin_until(client.service_is_ready, timeout, f"{node_fqn}/get_parameters")
    # a query: sent again while no reply came (a reply can be lost to discovery, services.py)
    reply = query(client, GetParameters.Request(names=names),
                  lambda s: ros.executor.spin_once(timeout_sec=s), timeout)
    assert reply is not None, f"no reply of {node_fqn}/get_parameters within {timeout:g} s"
    return {n: parameter_value_to_python(v) for n, v in zip(names, reply.values)}


#: node -> (setting its /**/<node> section of config/cell.yaml sets, that value,
#: the command-line value); and use_sim_time where the file sets it true.
OVERRIDES = {
    "simulator": ("real_time_factor", 10.0, 20.0),
    "planner": ("control_rate", 50.0, 20.0),
    "monitor": ("max_data_age", 0.5, 0.8),
}


@pytest.mark.parametrize("node", sorted(OVERRIDES))
def test_minus_p_beats_the_params_file_for_every_node(ros, procs, node):
    name, in_file, wanted = OVERRIDES[node]
    from rheo_shaping.params.config import node_parameters, read_yaml
    file_values = node_parameters(read_yaml(CELL_YAML), node, CELL_YAML)
    assert file_values[name] == in_file, "the shipped file sets it in the node's section"
    args = ["--ros-args", "--params-file", str(CELL_YAML), "-p", f"{name}:={wanted!r}"]
    names = [name]
    if file_values.get("use_sim_time"):
        args += ["-p", "use_sim_time:=false"]
        names.append("use_sim_time")
    proc = procs(node, *args)
    got = _get_parameters(ros, f"/{node}", names)
    assert got[name] == wanted, proc.text()
    if "use_sim_time" in names:
        assert got["use_sim_time"] is False, proc.text()


def test_node_sections_apply_in_a_namespace(ros, procs):
    """/**/planner matches /cell2/planner (a plain 'planner:' key would not)."""
    proc = procs("planner", "--ros-args", "--params-file", str(CELL_YAML),
                 "-r", "__ns:=/cell2", "-p", "control_rate:=25.0")
    got = _get_parameters(ros, "/cell2/planner", ["control_rate", "use_sim_time"])
    assert got == {"control_rate": 25.0, "use_sim_time": True}, proc.text()


@pytest.mark.parametrize("node", ["simulator", "planner", "monitor"])
def test_node_executables_print_their_version(node):
    import rheo_shaping
    proc = subprocess.run([str(BIN / node), "--version"], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout
    assert proc.stdout.strip() == f"{node} (rheo_shaping) {rheo_shaping.__version__}"
