"""Building (and reading) the cell's ROS messages; frame ``cake``, SI units.

The 2-D model lives in the x-z plane of frame ``cake``: a point (x, z) is the
ROS point (x, 0, z).  Times are integer nanoseconds on the publishing node's
clock (simulated time when the cell runs on /clock).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from builtin_interfaces.msg import Duration as DurationMsg
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, PoseStamped, WrenchStamped
from rosgraph_msgs.msg import Clock
from std_msgs.msg import ColorRGBA, Float64, Float64MultiArray, Header, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray
from ..params.node_params import CAKE_FRAME
from ..units import NS

FRAME = CAKE_FRAME
JOINTS = ("tool_x", "tool_z")


# -- time -----------------------------------------------------------------------
def time_msg(ns: int) -> TimeMsg:
    ns = int(ns)
    return TimeMsg(sec=ns // NS, nanosec=ns % NS)


def stamp_ns(stamp: TimeMsg) -> int:
    return int(stamp.sec) * NS + int(stamp.nanosec)


def duration_msg(seconds: float) -> DurationMsg:
    ns = int(round(seconds * NS))
    return DurationMsg(sec=ns // NS, nanosec=ns % NS)


def header(ns: int) -> Header:
    return Header(stamp=time_msg(ns), frame_id=FRAME)


def clock_msg(ns: int) -> Clock:
    return Clock(clock=time_msg(ns))


# -- sheet and tool --------------------------------------------------------------
def profile_msg(points: np.ndarray, ns: int) -> PoseArray:
    """Centres of the masses, (N, 2) [m], as poses (identity orientation)."""
    msg = PoseArray(header=header(ns))
    poses = []
    for x, z in np.asarray(points, float):
        pose = Pose()
        pose.position.x, pose.position.z = float(x), float(z)
        poses.append(pose)
    msg.poses = poses
    return msg


def profile_points(msg: PoseArray) -> np.ndarray:
    """(N, 2) [m] from a /sheet/profile message."""
    return np.array([[p.position.x, p.position.z] for p in msg.poses], dtype=float).reshape(-1, 2)


def tensions_msg(tension: Sequence[float] | np.ndarray) -> Float64MultiArray:
    """Axial force [N] of every link, top bond to workplane bond; dim[0] labelled "link"."""
    values = [float(v) for v in tension]
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label="link", size=len(values), stride=len(values))]
    msg.layout.data_offset = 0
    msg.data = values
    return msg


def float_msg(value: float) -> Float64:
    return Float64(data=float(value))


def pose_msg(xz: Sequence[float] | np.ndarray, ns: int) -> PoseStamped:
    msg = PoseStamped(header=header(ns))
    msg.pose.position.x, msg.pose.position.z = float(xz[0]), float(xz[1])
    msg.pose.orientation.w = 1.0
    return msg


def pose_xz(msg: PoseStamped) -> tuple[float, float]:
    return float(msg.pose.position.x), float(msg.pose.position.z)


def wrench_msg(force_xz: Sequence[float] | np.ndarray, ns: int) -> WrenchStamped:
    """Force [N] the sheet exerts on the tool."""
    msg = WrenchStamped(header=header(ns))
    msg.wrench.force.x, msg.wrench.force.z = float(force_xz[0]), float(force_xz[1])
    return msg


# -- plan -------------------------------------------------------------------------
def trajectory_msg(plan, t0_ns: int, period: float) -> JointTrajectory:
    """A :class:`~rheo_shaping.planning.plans.Plan` as joints ``tool_x``, ``tool_z``.

    ``header.stamp`` is when the plan starts (t = 0 of the plan); points every
    ``period`` [s] and at every jerk switch, with positions, velocities and
    accelerations.
    """
    knots = plan.knots(include_phases=True)
    grid = np.arange(0.0, plan.duration, period) if plan.duration > 0 else np.zeros(1)
    times = np.unique(np.concatenate([grid, knots, [plan.duration]]))
    times = times[(times >= 0.0) & (times <= plan.duration)]
    pos, vel, acc = plan.sample_many(times)
    msg = JointTrajectory(header=header(t0_ns), joint_names=list(JOINTS))
    points = []
    for t, p, v, a in zip(times, pos, vel, acc):
        points.append(JointTrajectoryPoint(positions=[float(p[0]), float(p[1])],
                                           velocities=[float(v[0]), float(v[1])],
                                           accelerations=[float(a[0]), float(a[1])],
                                           time_from_start=duration_msg(float(t))))
    msg.points = points
    return msg


# -- diagnostics ------------------------------------------------------------------
LEVELS = {"OK": DiagnosticStatus.OK, "WARN": DiagnosticStatus.WARN,
          "ERROR": DiagnosticStatus.ERROR, "STALE": DiagnosticStatus.STALE}


def hardware_id(namespace: str) -> str:
    """The hardware id of a cell's diagnostics: ``shaping_cell`` in the root namespace,
    ``shaping_cell/cell2`` in ``/cell2`` (all cells report on the absolute /diagnostics)."""
    ns = namespace.strip("/")
    return "shaping_cell" + (f"/{ns}" if ns else "")


#: Each node's diagnostic task (the part of a status name after ``node: ``).
TASKS = {"simulator": "sheet", "monitor": "tension", "lifecycle_manager": "cell lifecycle",
         "gap_watch": "model gap", "planner": "closed loop"}


def status_name(namespace: str, node: str) -> str:
    """diagnostic_updater's ``node: task`` with the cell's namespace in front, so that two
    cells on one /diagnostics stay apart under an aggregator: ``monitor: tension`` in the
    root namespace, ``cellA/monitor: tension`` in ``/cellA``."""
    ns = namespace.strip("/")
    return f"{ns + '/' if ns else ''}{node}: {TASKS[node]}"


def diagnostics_msg(ns: int, name: str, level: str, message: str, values: dict,
                    hardware_id: str = "shaping_cell") -> DiagnosticArray:
    """One status on ``/diagnostics`` stamped ``ns`` [ns] (the node's clock: the cell's one
    stamp source).  A node does not say STALE of itself (the aggregator says it of a status
    that stops): a node still waiting reports WARN."""
    level = "WARN" if level == "STALE" else level
    status = DiagnosticStatus(level=LEVELS[level], name=name, message=message,
                              hardware_id=hardware_id,
                              values=[KeyValue(key=str(k), value=_fmt(v)) for k,
                                      v in values.items()])
    msg = DiagnosticArray(status=[status])
    msg.header.stamp = time_msg(ns)
    return msg


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


# -- markers ----------------------------------------------------------------------
def tension_colour(tension: float, F_break: float) -> ColorRGBA:
    """Green (slack) through yellow to red (F_break and above)."""
    s = 0.0 if not np.isfinite(tension) else min(max(tension / F_break, 0.0), 1.0)
    if not np.isfinite(tension):
        return ColorRGBA(r=1.0, g=0.0, b=1.0, a=1.0)   # magenta: no valid tension
    return ColorRGBA(r=min(2.0 * s, 1.0), g=min(2.0 * (1.0 - s), 1.0), b=0.0, a=1.0)


def _points(xz: np.ndarray) -> list[Point]:
    return [Point(x=float(x), y=0.0, z=float(z)) for x, z in np.asarray(xz, float)]


def markers_msg(ns: int, nodes: np.ndarray, tension: np.ndarray, F_break: float, thickness: float,
                tool_outline: np.ndarray, cake_outline: np.ndarray) -> MarkerArray:
    """The sheet (coloured by tension), its masses, the tool and the cake outline."""
    h = header(ns)
    sheet = Marker(header=h, ns="sheet", id=0, type=Marker.LINE_LIST, action=Marker.ADD)
    sheet.pose.orientation.w = 1.0
    sheet.scale.x = float(thickness)
    pts, cols = [], []
    nodes = np.asarray(nodes, float)
    for i in range(len(nodes) - 1):
        c = tension_colour(float(tension[i]), F_break)
        pts += _points(nodes[i:i + 2])
        cols += [c, c]
    sheet.points, sheet.colors = pts, cols
    masses = Marker(header=h, ns="sheet_masses", id=1, type=Marker.SPHERE_LIST, action=Marker.ADD)
    masses.pose.orientation.w = 1.0
    masses.scale.x = masses.scale.y = masses.scale.z = float(thickness)
    masses.color = ColorRGBA(r=0.9, g=0.9, b=0.85, a=0.6)
    masses.points = _points(nodes[1:-1])
    tool = Marker(header=h, ns="tool", id=2, type=Marker.LINE_STRIP, action=Marker.ADD)
    tool.pose.orientation.w = 1.0
    tool.scale.x = 0.001
    tool.color = ColorRGBA(r=0.2, g=0.4, b=1.0, a=1.0)
    outline = np.asarray(tool_outline, float)
    tool.points = _points(np.vstack([outline, outline[:1]]))
    cake = Marker(header=h, ns="cake", id=3, type=Marker.LINE_STRIP, action=Marker.ADD)
    cake.pose.orientation.w = 1.0
    cake.scale.x = 0.001
    cake.color = ColorRGBA(r=0.6, g=0.4, b=0.2, a=1.0)
    cake.points = _points(cake_outline)
    return MarkerArray(markers=[sheet, masses, tool, cake])


def gap_markers_msg(ns: int, model_nodes: np.ndarray | None, frame: np.ndarray | None,
                    thickness: float, level: str) -> MarkerArray:
    """The gap watch's view: the model's centreline (``gap_model``, blue; orange on WARN, red
    on ERROR) and the newest camera frame it judged (``gap_measured``, white points)."""
    h = header(ns)
    out = []
    if model_nodes is not None:
        line = Marker(header=h, ns="gap_model", id=0, type=Marker.LINE_STRIP, action=Marker.ADD)
        line.pose.orientation.w = 1.0
        line.scale.x = 0.5 * float(thickness)
        line.color = {"WARN": ColorRGBA(r=1.0, g=0.6, b=0.0, a=1.0),
                      "ERROR": ColorRGBA(r=1.0, g=0.0, b=0.0, a=1.0)}.get(
            level, ColorRGBA(r=0.1, g=0.5, b=1.0, a=1.0))
        line.points = _points(model_nodes)
        out.append(line)
    if frame is not None:
        pts = Marker(header=h, ns="gap_measured", id=1, type=Marker.POINTS, action=Marker.ADD)
        pts.pose.orientation.w = 1.0
        pts.scale.x = pts.scale.y = float(thickness)
        pts.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=0.9)
        pts.points = _points(frame)
        out.append(pts)
    return MarkerArray(markers=out)
