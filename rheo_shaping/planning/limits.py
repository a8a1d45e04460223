"""The tool's path limits (speed, acceleration, jerk), shared by plans and their pieces.
No ROS imports here."""
from __future__ import annotations

from dataclasses import dataclass

from ..params.validators import check_positive


@dataclass(frozen=True)
class MotionLimits:
    """Path limits of the tool: ``v_max`` [m/s], ``a_max`` [m/s^2], ``j_max`` [m/s^3].

    They bound the Euclidean norm of the tool's velocity, acceleration and
    jerk in the x-z plane.  Each must be finite and > 0.
    """

    v_max: float
    a_max: float
    j_max: float

    def __post_init__(self) -> None:
        for name, unit in (("v_max", "m/s"), ("a_max", "m/s^2"), ("j_max", "m/s^3")):
            check_positive(f"MotionLimits.{name} [{unit}]", getattr(self, name))

    def scaled(self, factor: float) -> "MotionLimits":
        """All three limits multiplied by ``factor`` (> 0)."""
        check_positive("factor [-]", factor)
        return MotionLimits(self.v_max * factor, self.a_max * factor, self.j_max * factor)
