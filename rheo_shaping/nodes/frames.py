"""The cell's frame ``cake`` on ``/tf_static``, as tf2's static broadcaster sends it.

Every message of the cell is stamped in frame ``cake`` (docs/interfaces.md).  The
simulator tells tf2 where that frame stands: one ``geometry_msgs/TransformStamped`` from its
``cake_parent_frame`` (default ``world``) to ``cake``, at ``cake_xyz`` turned by
``cake_rpy``, in a ``tf2_msgs/TFMessage`` on the absolute ``/tf_static`` with tf2_ros's
static QoS (depth 1, transient local, reliable: a late rviz2 or bag recorder gets it).

tf2_msgs is not a wheel on PyPI (``dev.py setup`` builds it into ``.venv``; a ROS
installation has it): where it does not import, the node says so once and runs without
``/tf_static``.
"""
from __future__ import annotations

import math
from typing import Sequence

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node

from ..params.node_params import CAKE_FRAME, SimulatorNodeParams
from . import messages as m
from . import topics as T

_said_missing = False       # the missing tf2_msgs is said once per process


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, ...]:
    """(x, y, z, w) of the rotation by ``roll`` about x, then ``pitch`` about y, then
    ``yaw`` about z, all fixed axes [rad] (tf2's ``Quaternion::setRPY``)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def cake_transform(parent: str, xyz: Sequence[float], rpy: Sequence[float],
                   ns: int) -> TransformStamped:
    """The transform from ``parent`` to ``cake`` stamped ``ns`` [ns]."""
    t = TransformStamped()
    t.header.stamp = m.time_msg(ns)
    t.header.frame_id = parent
    t.child_frame_id = CAKE_FRAME
    tr, q = t.transform.translation, t.transform.rotation
    tr.x, tr.y, tr.z = (float(v) for v in xyz)
    q.x, q.y, q.z, q.w = quaternion_from_rpy(*(float(v) for v in rpy))
    return t


def publish_cake_frame(node: Node, settings: SimulatorNodeParams):
    """Publish the cake frame once on ``/tf_static`` (latched); the publisher, or None when
    ``cake_parent_frame`` is empty or tf2_msgs does not import (said once)."""
    global _said_missing
    if not settings.cake_parent_frame:
        return None
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError as exc:
        if not _said_missing:
            _said_missing = True
            node.get_logger().warning(
                f"no frame on {T.TF_STATIC}: tf2_msgs does not import ({exc}); install it "
                f"(apt: ros-jazzy-tf2-msgs; the venv: python3 dev.py setup builds it), or set "
                f"cake_parent_frame to '' to silence this")
        return None
    pub = node.create_publisher(TFMessage, T.TF_STATIC, T.TF_STATIC_QOS)
    s = settings
    pub.publish(TFMessage(transforms=[cake_transform(
        s.cake_parent_frame, s.cake_xyz, s.cake_rpy, node.get_clock().now().nanoseconds)]))
    node.get_logger().info(
        f"frame {CAKE_FRAME} on {T.TF_STATIC}: parent {s.cake_parent_frame}, xyz "
        f"{list(s.cake_xyz)} m, rpy {list(s.cake_rpy)} rad")
    return pub
