"""ROS 2 nodes of rheo_shaping (the only part of the package that imports rclpy).

SCAFFOLD: ``simulator``, ``planner`` and ``monitor`` are placeholders that
only start, join the ROS graph and stop cleanly; the ROS-cell work replaces
them. The physics core (everything outside this subpackage) must not import
anything from here.
"""
