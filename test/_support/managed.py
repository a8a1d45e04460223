"""Managed cells as processes (test_lifecycle.py, test_busy_managed.py): the executables,
a small params file, the manager's status and a recorder of one cell."""
from __future__ import annotations

import json
from dataclasses import replace

import yaml

from rheo_shaping.nodes import topics as T
from rheo_shaping.params.cell import CellParams
from rheo_shaping.params.config import dump_cell

MANAGED = {"simulator": "simulator_managed", "monitor": "monitor_managed",
           "planner": "planner_managed"}
#: Eight processes share the busy machine: 10x real time, as test_namespaces.py.
REAL_TIME_FACTOR = 10.0


def manager_status(rec, ns: str) -> dict:
    """The newest ``~/status`` of the manager of the cell in ``ns`` ({} none yet)."""
    last = rec.last(f"{ns}/lifecycle_manager/status")
    return json.loads(last.data) if last is not None else {}


def managed_params(tmp_path):
    """A 15-mass cell at 10x, planner and monitor on its clock (node sections keyed
    /**/<node> apply in any namespace, docs/ros.md)."""
    data = yaml.safe_load(dump_cell(replace(CellParams(), sheet=replace(CellParams().sheet,
                                                                        n_masses=15))))
    data["/**/simulator"] = {"ros__parameters": {"real_time_factor": REAL_TIME_FACTOR}}
    for name in ("planner", "monitor"):
        data[f"/**/{name}"] = {"ros__parameters": {"use_sim_time": True}}
    params = tmp_path / "cell.yaml"
    params.write_text(yaml.safe_dump(data, sort_keys=False))
    return params


def cell_recorder(ros, observer: str, ns: str, depth: int = 100):
    """A recorder of the manager's status, the planner's state and /diagnostics of the cell
    in ``ns``, and the planner's newest state ("" none yet)."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from _support.ros import Recorder
    rec = Recorder(ros.node(observer),
                   {f"{ns}/lifecycle_manager/status": (T.MANAGER_STATUS.type, True),
                    T.PLANNER_STATE.in_namespace(ns): (T.PLANNER_STATE.type, True)})
    rec.add(T.DIAGNOSTICS.name, T.DIAGNOSTICS.type,
            QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE))

    def planner_state() -> str:
        last = rec.last(T.PLANNER_STATE.in_namespace(ns))
        return last.data if last is not None else ""
    return rec, planner_state
