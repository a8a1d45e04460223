"""The shaping tool's cross-section from its parameters (frame of its reference point)."""
from __future__ import annotations

import numpy as np

from .polygon import RoundedConvexPolygon
from ..params.cell import ToolParams


def tool_shape(tool: ToolParams) -> RoundedConvexPolygon:
    """A circle, rounded rectangle (centred on the reference point) or convex polygon."""
    if tool.shape == "circle":
        return RoundedConvexPolygon.circle(tool.radius)
    if tool.shape == "rounded_rectangle":
        return RoundedConvexPolygon.rounded_rectangle(tool.width, tool.height, tool.corner_radius)
    vertices = np.asarray(tool.vertices, dtype=float)
    if vertices.size % 2:
        raise ValueError(
            f"parameter 'tool.vertices' has {vertices.size} values: expected x, z pairs")
    return RoundedConvexPolygon.convex_polygon(vertices.reshape(-1, 2), tool.corner_radius)
