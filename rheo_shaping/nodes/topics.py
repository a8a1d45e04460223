"""Every topic of the cell in one place: name, message type and QoS (docs/ros.md).

The names are **relative** (no leading ``/``): in the root namespace they are
the contract's names of docs/interfaces.md (``sheet/profile`` is ``/sheet/profile``),
and the whole cell moves with the nodes' namespace (``--ros-args -r
__ns:=/cell2`` gives ``/cell2/sheet/profile``).  Services are private
(``~/reset``: ``/cell2/simulator/reset``).

``/clock`` and ``/tf_static`` are absolute, where ROS itself and its tools look
for them: rclpy's time source subscribes to ``/clock``, and rviz2, ``ros2 bag`` and
tf2 read ``/clock`` and ``/tf_static`` in any namespace.  Several simulated cells on
one domain give each its own clock with the remap ``-r /clock:=clock`` on every
node of the cell, the simulator included (:data:`CLOCK_REMAP`; the launch file's
``clock_topic:=clock``, ``rheo-shaping cell --clock-topic clock``).

Nodes, the cell runner, the recorder and the tests all take their names and
QoS from here.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseStamped, WrenchStamped
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64, Float64MultiArray, String, UInt64
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray


def _qos(depth: int, durability: DurabilityPolicy = DurabilityPolicy.VOLATILE,
         deadline_s: float | None = None) -> QoSProfile:
    kwargs = {} if deadline_s is None else {"deadline": Duration(seconds=deadline_s)}
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE, durability=durability,
                      history=HistoryPolicy.KEEP_LAST, **kwargs)


#: State topics: reliable, volatile, a short queue (what a subscriber keeps unread).
STATE_QOS = _qos(10)
#: History a publisher of state keeps for its slower readers: one that a busy machine
#: deschedules for 0.5 s of a 200 Hz stream (10x faster than real time) loses nothing it
#: asked to keep (each reader still keeps only its own queue, e.g. the monitor's 10).
WRITER_DEPTH = 100


def writer_qos(qos: QoSProfile) -> QoSProfile:
    """``qos`` with a publisher's history of at least :data:`WRITER_DEPTH` samples."""
    out = copy.copy(qos)
    out.depth = max(qos.depth, WRITER_DEPTH)
    return out


#: /tool/command: reliable with room for a whole batch of set-points.
COMMAND_QOS = _qos(1000)
#: The plan, the abort and the planner's state: late joiners get the last one.
LATCHED_QOS = _qos(1, DurabilityPolicy.TRANSIENT_LOCAL)
#: /shaping/ready: only fresh beats mean anything.
HEARTBEAT_QOS = _qos(1)
#: /clock: the latest value only.
CLOCK_QOS = _qos(1)
#: /tf_static: tf2_ros's StaticTransformBroadcaster's (Jazzy): depth 1, transient local,
#: reliable; every static frame of a publisher in its one latched message.
TF_STATIC_QOS = _qos(1, DurabilityPolicy.TRANSIENT_LOCAL)
#: /sheet/markers: the newest picture only.
MARKER_QOS = _qos(1)


def tension_qos(deadline_s: float) -> QoSProfile:
    """QoS of the tension topics with a deadline [s] (offered by the simulator,
    requested by the monitor: ``max_data_age``)."""
    return _qos(10, deadline_s=deadline_s)


@dataclass(frozen=True)
class Topic:
    """One topic: relative ``name``, message ``type``, ``qos`` (without a deadline)."""

    name: str
    type: type
    qos: QoSProfile

    @property
    def contract(self) -> str:
        """The name in the root namespace (docs/interfaces.md), e.g. ``/sheet/profile``."""
        return self.name if self.name.startswith("/") else "/" + self.name

    def in_namespace(self, namespace: str) -> str:
        """The fully qualified name in ``namespace`` (``/cell2`` -> ``/cell2/sheet/profile``);
        an absolute name (``/diagnostics``) stays as it is."""
        if self.name.startswith("/"):
            return self.name
        ns = "/" + namespace.strip("/")
        return (ns.rstrip("/") + "/" + self.name) if ns != "/" else self.contract


PROFILE = Topic("sheet/profile", PoseArray, STATE_QOS)
MEASURED_PROFILE = Topic("sheet/measured_profile", PoseArray, STATE_QOS)
TENSIONS = Topic("sheet/tensions", Float64MultiArray, STATE_QOS)
CONTACT_TENSION = Topic("sheet/contact_tension", Float64, STATE_QOS)
TOOL_POSE = Topic("tool/pose", PoseStamped, STATE_QOS)
TOOL_WRENCH = Topic("tool/wrench", WrenchStamped, STATE_QOS)
MARKERS = Topic("sheet/markers", MarkerArray, MARKER_QOS)
#: The simulator's clock: absolute, as rclpy's time source, rviz2 and ``ros2 bag`` read it
#: (``-r /clock:=clock`` on every node of a cell moves it into the cell's namespace).
CLOCK = Topic("/clock", Clock, CLOCK_QOS)
#: A clock in the namespace: what ``-r /clock:=clock`` makes of :data:`CLOCK`, and what
#: ``rheo-shaping replay --namespace`` publishes.
NAMESPACED_CLOCK = Topic("clock", Clock, CLOCK_QOS)
TOOL_COMMAND = Topic("tool/command", PoseStamped, COMMAND_QOS)
PLANNED_TRAJECTORY = Topic("tool/planned_trajectory", JointTrajectory, LATCHED_QOS)
ABORT = Topic("shaping/abort", String, LATCHED_QOS)
READY = Topic("shaping/ready", Bool, HEARTBEAT_QOS)
PLANNER_STATE = Topic("shaping/planner_state", String, LATCHED_QOS)
#: The monitor's acknowledgement: the DDS sequence number of the newest /sheet/tensions
#: sample it has judged (the simulator runs at most ``monitor_lead`` samples ahead of it).
CHECKED = Topic("shaping/checked", UInt64, HEARTBEAT_QOS)
#: Absolute, as the ecosystem reads it (diagnostic_aggregator, rqt_robot_monitor): every
#: cell's nodes report there, told apart by the status name and the hardware id (the cell's
#: namespace, rheo_shaping.nodes.messages.hardware_id).
DIAGNOSTICS = Topic("/diagnostics", DiagnosticArray, STATE_QOS)
#: The simulator's cell (rheo_shaping.params.fingerprint.cell_message, JSON): planner and
#: monitor refuse to run on another cell.
CELL = Topic("shaping/cell", String, LATCHED_QOS)
#: The planner the simulator follows (the fully qualified node name of the /tool/command
#: writer it is bound to, "" for none); a planner makes its writer only when it is "".
COMMANDER = Topic("shaping/commander", String, LATCHED_QOS)
#: Who is up: every node announces itself once (JSON: name, start time, pid); a second
#: node of a name yields to the one that started first (docs/safety.md, "One of each").
PRESENCE = Topic("shaping/presence", String,
                 QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL,
                            history=HistoryPolicy.KEEP_LAST))

#: A managed node's heartbeat (JSON: its lifecycle state, transitions done, process id):
#: the lifecycle manager tells a dead or frozen node by its silence (rheo_shaping.nodes.managed).
HEARTBEAT = Topic("~/heartbeat", String, HEARTBEAT_QOS)
#: The lifecycle manager's state (JSON: phase, reason, what it waits for, each node's state).
MANAGER_STATUS = Topic("~/status", String, LATCHED_QOS)
#: The gap watch (rheo_shaping.gapwatch, issue 29): its residuals and state (JSON, on every
#: publish_period), the verdict of the diagnosis it started (JSON, latched), the model's profile.
GAP = Topic("shaping/gap", String, STATE_QOS)
GAP_DIAGNOSIS = Topic("shaping/gap_diagnosis", String, LATCHED_QOS)
GAP_MARKERS = Topic("shaping/gap_markers", MarkerArray, MARKER_QOS)
#: The planner's closed loop (``adaptive``): each refresh's estimate and re-plan (JSON, SI
#: units; rheo_shaping.adaptive.online.OnlineStep.as_dict).
ESTIMATE = Topic("shaping/estimate", String, LATCHED_QOS)

#: Every topic of the cell, by its contract name.
ALL: dict[str, Topic] = {t.contract: t for t in (
    PROFILE, MEASURED_PROFILE, TENSIONS, CONTACT_TENSION, TOOL_POSE, TOOL_WRENCH, MARKERS, CLOCK,
    TOOL_COMMAND, PLANNED_TRAJECTORY, ABORT, READY, PLANNER_STATE, CHECKED, DIAGNOSTICS, CELL,
    COMMANDER,
    PRESENCE, GAP, GAP_DIAGNOSIS, GAP_MARKERS, ESTIMATE)}

#: The cell's clock in its namespace (several simulated cells on one domain): the remap for
#: every node of the cell, the simulator's /clock publisher and every time source alike.
CLOCK_REMAP = ("-r", "/clock:=clock")
#: Where the simulator's clock may be (the launch file's ``clock_topic``, ``rheo-shaping
#: cell --clock-topic``): the absolute ``/clock``, or the namespace's ``clock``.
CLOCK_TOPICS = (CLOCK.name, NAMESPACED_CLOCK.name)
#: tf2's static transforms, absolute as tf2 and rviz2 read them (tf2_msgs/TFMessage; the
#: type is imported where it is published, since tf2_msgs may be missing).
TF_STATIC = "/tf_static"
