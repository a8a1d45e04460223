"""Unit constants shared by the core, the nodes and the tests (a leaf: imports nothing)."""

#: nanoseconds per second (ROS stamps and clocks count integer ns)
NS = 1_000_000_000
