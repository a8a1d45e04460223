"""rheo_shaping: robotic shaping of thin rheological sheets over a mould.

The physics core (material, identification, sheet model, geometry, scenarios,
planning, diagnosis) imports no ROS; the ROS 2 nodes live in
:mod:`rheo_shaping.nodes`.
"""
__version__ = "0.1.0"
