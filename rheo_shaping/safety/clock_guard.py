"""A clock you cannot lie to: what a node accepts of ``/clock`` (docs/safety.md).

One forged ``/clock`` message 30 s ahead once made the planner stream the next 30 s of its
plan at once; one with negative seconds killed it inside rclpy's time source.  A
:class:`ClockGuard` judges each clock value before the node's clock takes it: a negative
time, a time before the newest accepted one, or a jump forward by more than
``max_jump`` [s] is refused with a reason (the value is not applied; the node stops the
run with that reason).  Equal values are fine (the simulator re-publishes its clock while
it holds at the start).
"""
from __future__ import annotations

from ..units import NS


class ClockGuard:
    """Judges simulated-clock values [ns]; the newest accepted one is :attr:`last_ns`."""

    def __init__(self, max_jump: float):
        if not max_jump > 0.0:
            raise ValueError(f"max_jump must be > 0 s, got {max_jump!r}")
        self.max_jump = float(max_jump)     # s
        self.last_ns: int | None = None
        self.refused = 0

    def check(self, t_ns: int) -> str:
        """"" if ``t_ns`` is accepted (and becomes :attr:`last_ns`), else the reason."""
        reason = self._judge(int(t_ns))
        if reason:
            self.refused += 1
        else:
            self.last_ns = int(t_ns)
        return reason

    def _judge(self, t_ns: int) -> str:
        if t_ns < 0:
            return f"/clock is negative ({t_ns / NS:.9f} s)"
        last = self.last_ns
        if last is None:
            return ""
        if t_ns < last:
            return (f"/clock ran backward from {last / NS:.6f} s to {t_ns / NS:.6f} s "
                    f"({(last - t_ns) / NS:.6f} s)")
        if t_ns - last > self.max_jump * NS:
            return (f"/clock jumped forward by {(t_ns - last) / NS:.6f} s, from "
                    f"{last / NS:.6f} s to {t_ns / NS:.6f} s (max_clock_jump "
                    f"{self.max_jump:g} s)")
        return ""
