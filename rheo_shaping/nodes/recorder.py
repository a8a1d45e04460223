"""Records from a running cell, and records played back into ROS (docs/records.md).

:class:`CellRecorder` (``rheo-shaping record-cell``) subscribes to a cell's
``tool/pose``, ``sheet/measured_profile`` (a camera, or the simulator's simulated
one) and ``tool/wrench``, keeps the messages from the process start on (the stamp
of the first ``tool/command``, or the latched plan's start), and writes a record
directory: the rosbag2 MCAP bag with the messages on their own header stamps, and
``scenario.yaml``, the nominal cell (every effect off) from a params file or from
the running simulator's parameters.

:func:`replay` (``rheo-shaping replay``) publishes a record's messages back into
ROS in stamp order, paced on its stamps (``/clock`` too, so nodes on
``use_sim_time`` see the recorded time).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from rclpy.node import Node

from ..params.config import cell_from_flat
from ..sheet.effects import nominal
from ..params.cell import CellParams
from ..records.assembly import CellBuffer, RecordCellError, assemble  # noqa: F401 (API)
from ..records.record import Record
from ..records.bag import write_record
from ..planning.states import AT_REST, MOVING
from ..params.schema import iter_fields
from . import messages as m
from . import topics as T
from .session import eta, ros_session
from .services import query
from ..units import NS


class CellRecorder(Node):
    """Subscribes to one cell's measured topics and keeps them from the process start."""

    def __init__(self, **kwargs):
        super().__init__("record_cell", **kwargs)
        self.buf = CellBuffer()
        sub = self.create_subscription
        sub(T.TOOL_POSE.type, T.TOOL_POSE.name, self._on_pose, T.TOOL_POSE.qos)
        sub(T.MEASURED_PROFILE.type, T.MEASURED_PROFILE.name, self._on_profile,
            T.MEASURED_PROFILE.qos)
        sub(T.TOOL_WRENCH.type, T.TOOL_WRENCH.name, self._on_wrench, T.TOOL_WRENCH.qos)
        sub(T.TOOL_COMMAND.type, T.TOOL_COMMAND.name, self._on_command, T.TOOL_COMMAND.qos)
        sub(T.PLANNED_TRAJECTORY.type, T.PLANNED_TRAJECTORY.name, self._on_plan,
            T.PLANNED_TRAJECTORY.qos)
        sub(T.PLANNER_STATE.type, T.PLANNER_STATE.name, self._on_state, T.PLANNER_STATE.qos)
        self.last_rx = time.monotonic()

    # -- callbacks -----------------------------------------------------------------------
    def _seen(self, stamp: int) -> None:
        self.last_rx = time.monotonic()
        if self.buf.first_rx_ns is None:
            self.buf.first_rx_ns = stamp

    def _on_pose(self, msg) -> None:
        t = m.stamp_ns(msg.header.stamp)
        self._seen(t)
        x, z = m.pose_xz(msg)
        self.buf.pose.append((t, x, z))

    def _on_profile(self, msg) -> None:
        t = m.stamp_ns(msg.header.stamp)
        self._seen(t)
        self.buf.profile.append((t, m.profile_points(msg)))

    def _on_wrench(self, msg) -> None:
        t = m.stamp_ns(msg.header.stamp)
        self._seen(t)
        f = msg.wrench.force
        self.buf.wrench.append((t, float(f.x), float(f.z)))

    def _on_command(self, msg) -> None:
        self.buf.command(m.stamp_ns(msg.header.stamp), m.pose_xz(msg))

    def _on_plan(self, msg) -> None:
        self.buf.plan(m.stamp_ns(msg.header.stamp))

    def _on_state(self, msg) -> None:
        self.buf.state(msg.data, MOVING)

    # -- the record ----------------------------------------------------------------------
    def recorded_time(self) -> float:
        """Process time [s] of the newest pose (0 before the start)."""
        return self.buf.recorded_time()

    def record(self, scenario: CellParams, name: str) -> Record:
        """The record from the process start on (t = 0 at the start;
        :func:`rheo_shaping.records.assembly.assemble`)."""
        return assemble(self.buf, scenario, name)


def scenario_from_simulator(node: Node, executor, simulator: str, timeout: float) -> CellParams:
    """The nominal cell (effects off) from the running simulator's cell parameters."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python
    names = [fi.name for fi in iter_fields(CellParams)]
    client = node.create_client(GetParameters, f"{simulator}/get_parameters")
    end = time.monotonic() + timeout
    while not client.service_is_ready():
        if time.monotonic() > end:
            raise RecordCellError(f"no {simulator}/get_parameters service within {timeout:g} s: "
                                  f"is the simulator running (or give --params FILE)?")
        executor.spin_once(timeout_sec=0.05)
    reply = query(client, GetParameters.Request(names=names),
                  lambda s: executor.spin_once(timeout_sec=s), end - time.monotonic())
    if reply is None:
        raise RecordCellError(f"{simulator}/get_parameters did not answer")
    flat = {}
    for n, v in zip(names, reply.values):
        value = parameter_value_to_python(v)
        flat[n] = (tuple(float(x) for x in value)
                   if not isinstance(value, (str, bytes)) and hasattr(value, "__len__")
                   else value)
    return nominal(cell_from_flat(flat, f"{simulator}'s parameters"))


def record_cell(out: Path, *, namespace: str = "", scenario: CellParams | None = None,
                duration: float | None = None, idle_timeout: float = 5.0,
                timeout: float = 3600.0, force: bool = False,
                progress: Callable[[str], None] | None = None,
                start_stamp: float | None = None, start: bool = False) -> tuple[Path, Record]:
    """Record one run of the cell in ``namespace`` and write it to ``out``.

    Stops when the planner is done (or holds after an abort) and the record covers
    ``movement.process_time``, when ``duration`` [s] of process time is recorded, when
    the cell has been silent ``idle_timeout`` [s] of wall time after the start, after
    ``timeout`` [s], or on Ctrl-C; then writes what it has.  ``start``: once a pose and a
    camera frame have arrived (so the record has the state before the start), call the
    planner's ``~/start`` (a cell whose planner has ``autostart: false``).
    """
    args = ["record_cell", "--ros-args"]
    if namespace:
        args += ["-r", f"__ns:={namespace}"]
    with ros_session(args) as (context, executor, nodes):
        node = CellRecorder(context=context)
        nodes.append(node)
        executor.add_node(node)
        return _record(node, executor, context, out, scenario, namespace, duration, start,
                       timeout, idle_timeout, start_stamp, force, progress)


def _record(node: CellRecorder, executor, context, out: Path, scenario, namespace: str,
            duration, start: bool, timeout: float, idle_timeout: float, start_stamp, force: bool,
            progress) -> tuple[Path, Record]:
    """The recording of :func:`record_cell` in its ROS session."""
    say = progress or (lambda _msg: None)
    deadline = time.monotonic() + timeout        # one wall-clock budget for every phase
    cell = scenario if scenario is not None else scenario_from_simulator(
        node, executor, f"{namespace.rstrip('/')}/simulator", timeout)
    end_time = duration if duration is not None else cell.movement.process_time
    say(f"record-cell: waiting for the process start on "
        f"{T.TOOL_COMMAND.in_namespace(namespace or '/')}")
    if start:
        _start_planner(node, executor, f"{namespace.rstrip('/')}/planner",
                       deadline - time.monotonic(), say)
    t_first = None
    next_report = 0.0
    try:
        while time.monotonic() < deadline and context.ok():
            executor.spin_once(timeout_sec=0.05)
            t = node.recorded_time()
            if node.buf.start_ns is not None and t >= next_report:
                if t_first is None:
                    t_first = time.monotonic()
                elapsed = time.monotonic() - t_first
                left = eta(elapsed, t, end_time)
                say(f"  recorded {t:6.1f} / {end_time:g} s of process time{left} "
                    f"({len(node.buf.profile)} frames), planner {node.buf.planner_state}")
                next_report += 10.0
            if node.buf.complete(end_time, duration is not None, AT_REST):
                break
            if (node.buf.start_ns is not None
                    and time.monotonic() - node.last_rx > idle_timeout):
                say(f"record-cell: the cell has been silent for {idle_timeout:g} s: done")
                break
    except KeyboardInterrupt:
        say("record-cell: interrupted: writing what was recorded")
    rec = node.record(cell, out.name)
    start_ns = node.buf.start_ns
    assert start_ns is not None             # record() refuses a run that never started
    stamp = start_stamp if start_stamp is not None else start_ns / NS
    path = write_record(rec, out, start_stamp=stamp, force=force)
    return path, rec


def _start_planner(node: CellRecorder, executor, planner: str, timeout: float, say) -> None:
    from std_srvs.srv import Trigger
    end = time.monotonic() + timeout
    client = node.create_client(Trigger, f"{planner}/start")
    while not (node.buf.pose and node.buf.profile and client.service_is_ready()):
        if time.monotonic() > end:
            raise RecordCellError(f"no tool/pose and camera frame, or no {planner}/start "
                                  f"service, within {timeout:g} s: is the cell running?")
        executor.spin_once(timeout_sec=0.05)
    future = client.call_async(Trigger.Request())
    while not future.done():
        if time.monotonic() > end:
            raise RecordCellError(f"{planner}/start did not answer")
        executor.spin_once(timeout_sec=0.05)
    reply = future.result()
    if not reply.success:
        raise RecordCellError(f"{planner}/start refused: {reply.message}")
    say(f"record-cell: started the planner ({reply.message})")


# -- replay ----------------------------------------------------------------------------------
