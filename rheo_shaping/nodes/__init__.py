"""ROS 2 nodes of rheo_shaping (the only part of the package that imports rclpy).

``simulator``, ``planner`` and ``monitor`` (one module each, ``main(args=None)``
entry points), ``ros_params`` (ROS parameters declared from the schema),
``messages`` (message building) and ``cell`` (the three nodes in one process,
for ``rheo-shaping cell``).  See docs/ros.md.  The physics core (everything
outside this subpackage) must not import anything from here.
"""

#: Nothing to import: each node is an executable (``main``), started by its launcher.
__all__: list[str] = []
