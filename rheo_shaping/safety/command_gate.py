"""One commander: what a simulator (or a robot adapter) executes of ``/tool/command``.

:class:`CommandGate` is the simulator node's decision core for set-points (docs/safety.md,
"One commander"), modelled on ros2_control's joint limits enforced below the controller:

* **One source.**  The gate binds to the one publisher of ``/tool/command`` in the graph
  (its GID); a second publisher while it is bound, a message whose publication sequence
  number does not follow the bound writer's (a rogue writer's own count), or a set-point
  that arrives while the graph shows no single publisher is refused.  rclpy hands no
  publisher GID to a callback (Jazzy's message info holds the sequence numbers only), so the
  graph is checked on every message and the sequence number tells the bound writer's
  samples from another's.
* **The abort is honoured here too.**  ``/shaping/abort`` latches a hold: the tool stays
  where it is (the newest executed position) and set-points are ignored until
  :meth:`reset`, whatever the planner or anyone else streams.
* **Motion limits on what is executed.**  Each set-point is judged against the executed
  ones before it in time: a jump beyond ``max_jump`` [m], a speed (first divided difference)
  beyond ``max_speed`` [m/s], an acceleration (twice the second divided difference, a
  weighted average of the true acceleration of any C2 motion through the points, so bounded
  by its largest value) beyond ``max_accel`` [m/s^2] latches a hold with the reason.

A hold latches with its first reason (:attr:`held`); the node publishes it once.
Times are integer nanoseconds on the node's (or simulated) clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

from ..params.validators import PointLike
from ..units import NS

#: Set-points closer in time than this [ns] to the one before are judged for the jump only
#: (round-off of divided differences over tiny intervals).
MIN_GAP_NS = 100_000
#: Executed set-points kept to judge a replacement (a stop re-planned from the executed
#: pose replaces up to ``max_lead`` of them).
KEEP = 1000
#: Longest wall-clock time [s] a set-point waits for the graph to show its publisher.
GRAPH_WAIT = 5.0


@dataclass(frozen=True)
class ToolLimits:
    """Motion limits the executed tool path must keep (per axis magnitude in the x-z plane)."""

    max_speed: float      # m/s
    max_accel: float      # m/s^2
    max_jump: float       # m, between consecutive set-points


@dataclass(frozen=True)
class Publisher:
    """One publisher of ``/tool/command`` as the graph shows it."""

    node: str             # fully qualified node name
    gid: str              # hex


#: The node name the graph gives a writer before it knows the writer's node.
UNNAMED = "_NODE_NAME_UNKNOWN_"


class CommandGate:
    """Decides, per set-point, whether the tool follows it (see the module docstring)."""

    def __init__(self, limits: ToolLimits):
        self.limits = limits
        self.bound: Publisher | None = None
        self.held = ""                          # why the tool holds (latched), "" if it follows
        self.dropped = 0                        # set-points refused so far
        self._seq = 0                           # newest sequence number of the bound writer
        self._path: list[tuple[int, float, float]] = []   # accepted (t [ns], x, z), by time
        self._reported: set[str] = set()

    # -- latch ------------------------------------------------------------------------
    def hold(self, reason: str) -> bool:
        """Latch a hold (the first reason stays); True if this call latched it."""
        if self.held:
            return False
        self.held = reason
        return True

    def reset(self) -> None:
        """Re-arm: follow set-points again (the binding stays; the path starts afresh)."""
        self.held = ""
        self._path.clear()
        self._reported.clear()

    def report_once(self, key: str) -> bool:
        """True the first time ``key`` is seen since the last reset (report it then)."""
        if key in self._reported:
            return False
        self._reported.add(key)
        return True

    # -- one source -------------------------------------------------------------------
    def source(self, publishers: Sequence[Publisher], seq: int) -> str:
        """Why a set-point with publication sequence number ``seq`` is not from the bound
        planner, given the graph's publishers of ``/tool/command``; "" if it is."""
        pubs = list(publishers)
        self._follow_bound(pubs)
        if self.bound is None:
            if len(pubs) != 1:
                names = ", ".join(f"{p.node} ({p.gid[:12]})" for p in pubs) or "none"
                return (f"{len(pubs)} publishers of /tool/command in the graph ({names}): "
                        f"the simulator follows exactly one planner")
            self.bound = pubs[0]
        others = [p for p in pubs if p.gid != self.bound.gid]
        if others:
            names = ", ".join(f"{p.node} ({p.gid[:12]})" for p in others)
            return (f"a second publisher of /tool/command: {names}, besides the bound planner "
                    f"{self.bound.node}")
        if seq and seq <= self._seq:
            return (f"a set-point out of the bound planner's sequence (number {seq} after "
                    f"{self._seq}): another writer on /tool/command")
        self._seq = max(self._seq, int(seq))
        return ""

    def unbound_wait(self, publishers: Sequence[Publisher], waited_s: float) -> str:
        """What to do with set-points that came before the graph showed their writer, the
        oldest waiting ``waited_s`` [s] of wall time: "wait" while the graph shows no writer
        and the wait is under :data:`GRAPH_WAIT`, "hold" when it still shows none after it,
        "judge" once it shows one or more (each is then judged by :meth:`source`, in order)."""
        if publishers:
            return "judge"
        return "wait" if waited_s < GRAPH_WAIT else "hold"

    def commander(self, publishers: Sequence[Publisher]) -> str:
        """The bound planner's node name, or "" when none is bound: a bound writer that the
        graph no longer shows (its process ended, or its DDS lease ran out after a kill) is
        let go here, so a new planner can take the tool (what ``/shaping/commander`` says)."""
        self._follow_bound(list(publishers))
        return "" if self.bound is None else self.bound.node

    def _follow_bound(self, pubs: list[Publisher]) -> None:
        """The bound writer as the graph shows it now, found by its GID (the graph learns a
        writer's node name after the writer: the name may change from unknown to known); let
        go when the graph no longer shows it (the bound planner left: rebind on its next
        set-point)."""
        if self.bound is None:
            return
        same = [p for p in pubs if p.gid == self.bound.gid]
        if not same:
            self.bound, self._seq = None, 0
        elif same[0].node != self.bound.node and not same[0].node.endswith(UNNAMED):
            self.bound = same[0]

    # -- motion limits ----------------------------------------------------------------
    def judge(self, t_ns: int, x: float, z: float, tool_now: PointLike) -> str:
        """Why the set-point (x, z) [m] at ``t_ns`` breaks the limits; "" if it keeps them
        (it is then part of the executed path).  ``tool_now``: where the tool is [m], the
        reference of the first set-point of a path."""
        if not (math.isfinite(x) and math.isfinite(z)):
            return f"a set-point at ({x}, {z}) m is not finite"
        path = self._path
        while path and path[-1][0] >= t_ns:         # newest wins for a time already commanded
            path.pop()
        lim = self.limits
        # the last accepted set-point (t [ns], x, z); the tool, at no time, before the first
        t_prev, x_prev, z_prev = path[-1] if path else (None, float(tool_now[0]),
                                                        float(tool_now[1]))
        jump = math.hypot(x - x_prev, z - z_prev)
        if jump > lim.max_jump:
            return (f"a set-point {jump * 1e3:.3f} mm from the one before (max_tool_jump "
                    f"{lim.max_jump * 1e3:g} mm) at {t_ns / NS:.6f} s")
        if t_prev is not None and t_ns - t_prev >= MIN_GAP_NS:
            dt = (t_ns - t_prev) / NS
            v = (x - x_prev) / dt, (z - z_prev) / dt
            speed = math.hypot(*v)
            if speed > lim.max_speed * (1 + 1e-9):
                return (f"a set-point path at {speed * 1e3:.3f} mm/s (max_tool_speed "
                        f"{lim.max_speed * 1e3:g} mm/s) at {t_ns / NS:.6f} s")
            if len(path) >= 2 and t_prev - path[-2][0] >= MIN_GAP_NS:
                t0, x0, z0 = path[-2]
                dt0 = (t_prev - t0) / NS
                v0 = (x_prev - x0) / dt0, (z_prev - z0) / dt0
                acc = 2.0 * math.hypot(v[0] - v0[0], v[1] - v0[1]) / (dt + dt0)
                if acc > lim.max_accel * (1 + 1e-6) + 1e-9:
                    return (f"a set-point path accelerating at {acc * 1e3:.3f} mm/s^2 "
                            f"(max_tool_accel {lim.max_accel * 1e3:g} mm/s^2) at "
                            f"{t_ns / NS:.6f} s")
        path.append((int(t_ns), float(x), float(z)))
        if len(path) > KEEP:
            del path[:-KEEP]
        return ""


def malformed_setpoint(t_ns: int, x: float, z: float, frame: str, expected: str) -> str:
    """Why a ``/tool/command`` message is ignored outright ("" if it is a set-point to judge):
    no stamp, a position that is not finite, another frame than ``expected`` (empty: the
    default frame)."""
    if t_ns <= 0 or not (math.isfinite(x) and math.isfinite(z)):
        return f"ignored /tool/command with stamp {t_ns} ns at ({x}, {z})"
    if frame not in (expected, ""):
        return f"ignored /tool/command in frame '{frame}': expected '{expected}'"
    return ""


class Arrivals:
    """Set-points on their way through a :class:`CommandGate`: each judged by its source in
    the order it came; those that come before the graph shows their writer wait (ROS 2 can
    deliver a sample before the graph names its writer), for at most :data:`GRAPH_WAIT`.
    Items are opaque (the node's messages); times are steady-clock nanoseconds."""

    def __init__(self, gate: CommandGate):
        self.gate = gate
        self.waiting: list[tuple[object, int, int]] = []      # (item, seq, arrived)

    def clear(self) -> None:
        """Drop the set-points still waiting (a hold, a reset: none is followed)."""
        self.waiting.clear()

    def offer(self, item: object, seq: int, now_ns: int,
              publishers: Callable[[], Sequence[Publisher]]) -> tuple[list[object], str]:
        """A set-point with publication sequence number ``seq``: (the set-points to follow
        now, in order; why the tool holds, "" if it does not).  Nothing while the gate
        holds; after earlier ones still waiting for the graph, in order behind them."""
        if self.gate.held:
            return [], ""
        if self.waiting:
            self.waiting.append((item, seq, now_ns))
            return self.release(now_ns, publishers())
        pubs = list(publishers())
        if self.gate.bound is None and not pubs:
            self.waiting.append((item, seq, now_ns))        # judged once the graph shows it
            return [], ""
        why = self.gate.source(pubs, seq)
        return ([], why) if why else ([item], "")

    def release(self, now_ns: int, pubs: Sequence[Publisher]) -> tuple[list[object], str]:
        """The waiting set-points judged once the graph shows a writer (in order, up to the
        first refused), or a hold when it still shows none after :data:`GRAPH_WAIT`."""
        if not self.waiting:
            return [], ""
        what = self.gate.unbound_wait(pubs, (now_ns - self.waiting[0][2]) / NS)
        if what == "wait":
            return [], ""
        waiting, self.waiting = self.waiting, []
        if what == "hold":
            return [], f"set-points from a writer the graph does not show after {GRAPH_WAIT:g} s"
        out: list[object] = []
        for item, seq, _ in waiting:
            why = self.gate.source(pubs, seq)
            if why:
                return out, why
            out.append(item)
        return out, ""
