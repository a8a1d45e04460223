"""The ``simulator`` node's intake of ``/tool/command``: each set-point admitted from the
bound planner only (the core's :class:`~rheo_shaping.safety.command_gate.CommandGate`),
checked and buffered for the steps, or the tool held with the reason (a part of
:class:`~.simulator.SimulatorNode`)."""
from __future__ import annotations

from geometry_msgs.msg import PoseStamped
from std_msgs.msg import String

from ..safety.command_gate import Arrivals, Publisher, malformed_setpoint
from ..units import NS
from . import messages as m
from .guards import publishers_of
from .hosts import SimulatorMixin


class SetpointIntake(SimulatorMixin):
    """The simulator node's set-point intake (mixed into :class:`~.simulator.SimulatorNode`,
    whose gate, run and publishers it uses)."""

    # the node's state this sets (SimulatorNode._build initializes it)
    _commander: str | None
    arrivals: Arrivals

    def _command_publishers(self) -> list[Publisher]:
        return publishers_of(self, self._command_sub.topic_name)

    # -- set-points -------------------------------------------------------------------
    def _on_command(self, msg: PoseStamped, info=None) -> None:
        seq = int((info or {}).get("publication_sequence_number", 0))
        if self.gate.held and self.gate.report_once("held"):
            self.get_logger().warning(f"ignoring /tool/command while the tool holds "
                                      f"({self.gate.held}); ~/reset to re-arm")
        self._take(*self.arrivals.offer(msg, seq, self._steady.now().nanoseconds,
                                        self._command_publishers))

    def _take(self, follow: list, why: str) -> None:
        """Follow the admitted set-points in order (core: Arrivals), then hold if one was
        refused; /shaping/commander says whom the gate follows."""
        if follow or why:
            self._say_commander()
        for msg in follow:
            self._follow(msg)
            if self.gate.held:
                return
        if why:
            self._hold(why)

    def _say_commander(self, pubs: list[Publisher] | None = None) -> None:
        """/shaping/commander: the planner this simulator follows ("" for none), on a
        change (a bound writer the graph no longer shows is let go here)."""
        name = self.gate.commander(self._command_publishers() if pubs is None else pubs)
        if name != self._commander:
            self._commander = name
            self.pub_commander.publish(String(data=name))

    def _bind_waiting(self) -> None:
        """Set-points that came before the graph showed their writer: judged now."""
        if self.arrivals.waiting:
            self._take(*self.arrivals.release(self._steady.now().nanoseconds,
                                              self._command_publishers()))

    def _follow(self, msg: PoseStamped) -> None:
        """A set-point of the bound planner: checked, then buffered for the steps."""
        t = m.stamp_ns(msg.header.stamp)
        x, z = m.pose_xz(msg)
        ignored = malformed_setpoint(t, x, z, msg.header.frame_id, m.FRAME)
        if ignored:
            self.get_logger().warning(ignored, throttle_duration_sec=5.0)
            return
        why = self.gate.judge(t, x, z, self.sim.state.tool)
        if why:
            self._hold(why)
            return
        started = self.run.command(t, x, z)
        self._commands_fresh.received(self._steady.now().nanoseconds)
        if started:
            self.get_logger().info(
                f"process starts at {t / NS:.3f} s (set-point stamp {t / NS:.3f} s): first "
                f"set-point ({x * 1e3:.2f}, {z * 1e3:.2f}) mm")
        if self._pending:
            self._try_step()

    def _stream_live(self) -> bool:
        """Whether set-points still stream: one arrived within command_timeout (wall), judged
        fairly after a stall of this node's own process (:class:`Freshness`)."""
        return not self._commands_fresh.stale(self._steady.now().nanoseconds)

    def _on_checked(self, msg, info=None) -> None:
        """An acknowledgement: taken only from the bound monitor, never beyond the samples
        published; a second writer holds the tool."""
        trust = self._checked.take(info)
        if trust.foreign:
            self._hold(trust.reason)
            return
        why = self._lead.refusal(msg.data, "" if trust.trusted
                                 else trust.reason or "not the bound monitor's")
        if why:
            self.get_logger().warning(f"ignored /shaping/checked {msg.data} ({why})",
                                      throttle_duration_sec=5.0)
            return
        self._lead.on_checked(msg.data, self._steady.now().nanoseconds)
        if self._pending:
            self._try_step()
