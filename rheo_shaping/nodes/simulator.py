"""The ``simulator`` node: the sheet model of the cell under the streamed tool set-point.

It runs the core (:class:`rheo_shaping.sheet.simulation.Simulation`) and publishes
the cell's state (docs/interfaces.md): ``/sheet/profile``, ``/sheet/tensions``,
``/sheet/contact_tension``, ``/tool/pose``, ``/tool/wrench``, and
``/sheet/markers`` for RViz; its own status on ``/diagnostics``; and where the cell's
frame ``cake`` stands, once on ``/tf_static`` (:mod:`rheo_shaping.nodes.frames`).

Time.  A step timer on the steady clock fires every ``step_period``; each
step advances simulated time by ``real_time_factor x step_period``.  When
``real_time_factor`` is not 1 (or ``publish_clock`` is set) the simulator is
the clock of the cell: it publishes the absolute ``/clock`` (``-r /clock:=clock`` on
every node of the cell: the namespace's) and the other nodes run with
``use_sim_time:=true``.  ``/clock`` is published one step ahead of the
physics, so the planner streams the set-points of a step before the step is
computed; with ``lockstep`` the simulator waits (at most ``command_timeout``)
for the set-point of the step's end instead of guessing the motion, so the
streamed motion is simulated exactly.  It also waits while more than
``monitor_lead`` published tension samples are unacknowledged by the monitor
(``/shaping/checked``), so a stalled link stalls the simulation rather than
the monitor's view of it; and before the first set-point ``/clock`` holds
(lockstep, ``start_on_command``), so a plan whose first set-points arrive late
starts where the simulation is.  A step that computes slowly slows the
run down (it never skips physics); the achieved factor is logged and on
``/diagnostics``.  On wall time (factor 1, no /clock) each step advances to
the node clock's now, holding the newest set-point for the last few ms.

Process.  With ``start_on_command`` (default) the settled sheet waits at
process time 0 until the first ``/tool/command``; the process starts then,
with the tool at that set-point, exactly as the offline run starts with the
tool at its plan's start.  The tool follows the set-points linearly
interpolated by their stamps; after the newest one it holds.  At
``movement.process_time`` the node logs F_max, SF and Delta.  ``~/reset``
(std_srvs/Trigger) restarts the run (settled sheet, process time 0); the cell's
parameters are read-only while the node runs (docs/ros.md, "Parameters").
"""
from __future__ import annotations

import sys

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.publisher import Publisher
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ..sheet.geometry import Cake
from ..params.node_params import SimulatorNodeParams
from ..params.cell import CellParams, batch_cell
from ..planning.scenarios import movement_scenario
from ..sheet.cadence import Cadence, RateMeter
from ..sheet.setpoints import SetpointRun, SimClock, next_step
from ..sheet.tools import tool_shape
from ..params.fingerprint import cell_message
from ..safety.acknowledge import MonitorLead
from ..safety.command_gate import Arrivals, CommandGate, ToolLimits
from ..safety.watchdog import Freshness
from . import messages as m
from . import topics as T
from .frames import publish_cake_frame
from .guards import OwnedStream, Presence, with_message_info
from .simulator_intake import SetpointIntake
from .simulator_outputs import SimulatorOutputs
from .ros_params import SchemaParameters
from .spin import Yielded, build_or_destroy, run_node

from ..units import NS


class SimulatorNode(SetpointIntake, SimulatorOutputs, Node):
    """Steps the sheet under /tool/command and publishes the cell's state."""

    def __init__(self, message_info: bool = True, **node_kwargs):
        """``message_info``: the executor passes rmw message info to callbacks (rclpy's
        EventsExecutor, which the one-process cell uses, does not): the publication sequence
        number of each set-point is then checked too (:class:`CommandGate`)."""
        super().__init__('simulator', **node_kwargs)
        build_or_destroy(self, self._build, node_kwargs, message_info)

    def _build(self, node_kwargs: dict, message_info: bool) -> None:
        self.get_logger().info('starting: parameters, then the settled sheet')
        self.params = SchemaParameters(self, {"cell": CellParams, "settings": SimulatorNodeParams},
                                       cli_args=node_kwargs.get('cli_args'),
                                       on_change=lambda names: self._retune())
        self.cadence = Cadence(self.settings)        # what goes out when (core)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        pub = self._publisher
        self.pub_profile = pub(T.PROFILE)
        tension_qos = T.tension_qos(self.settings.offered_deadline)
        self.pub_tensions = pub(T.TENSIONS, tension_qos)
        self.pub_contact = pub(T.CONTACT_TENSION, tension_qos)
        self.pub_pose = pub(T.TOOL_POSE)
        self.pub_wrench = pub(T.TOOL_WRENCH)
        self.pub_markers = pub(T.MARKERS)
        self.pub_diag = pub(T.DIAGNOSTICS)
        self.pub_camera = pub(T.MEASURED_PROFILE)
        # where frame cake stands (cake_parent_frame), latched on /tf_static
        self.pub_tf_static = publish_cake_frame(self, self.settings)
        # only while this node is the clock (_configure_time)
        self.pub_clock: Publisher | None = None
        self._command_sub = self.create_subscription(
            T.TOOL_COMMAND.type, T.TOOL_COMMAND.name,
            with_message_info(lambda msg, info: self._on_command(msg, info)) if message_info
            else self._on_command, T.TOOL_COMMAND.qos)
        # one commander: the bound planner's set-points, within the tool's limits
        self.gate = CommandGate(self._tool_limits())
        self.arrivals = Arrivals(self.gate)        # set-points judged in order (core)
        self.pub_abort = self._latched(T.ABORT)
        self.create_subscription(T.ABORT.type, T.ABORT.name, self._on_abort, T.ABORT.qos)
        self.pub_cell = self._latched(T.CELL)
        self.pub_commander = self._latched(T.COMMANDER)
        self._commander: str | None = None          # what /shaping/commander said last
        self._commander_ns = 0                      # steady time it was last checked
        # acknowledgements only from the monitor of this namespace (a second writer holds)
        self._checked = OwnedStream(self, T.CHECKED.name, "monitor")
        self.create_subscription(
            T.CHECKED.type, T.CHECKED.name,
            with_message_info(lambda msg, info: self._on_checked(msg, info)) if message_info
            else self._on_checked, T.CHECKED.qos)
        self.create_service(Trigger, '~/reset', self._on_reset)

        self._pending = False          # a step is due (lockstep may hold it back)
        # steps wait for the monitor's acknowledgements of the tension samples (core)
        self._lead = self._monitor_lead()
        self.rate = RateMeter(self.settings.real_time_factor)
        seed = self.settings.camera_seed
        self._camera_rng = np.random.default_rng(seed if seed else None)
        self._configure_time()
        self._new_run()
        self._timer = self.create_timer(self.settings.step_period,
                                        self._on_timer, clock=self._steady)
        mode = (f"simulated time x{self.settings.real_time_factor:g}, publishing /clock"
                if self._sim_clock else "wall-clock time")
        self.get_logger().info(
            f"simulator up: {self.cell.sheet.n_masses} masses, movement "
            f"{self.cell.movement.number}, "
            f"{mode}, step {self.timeline.dt_ns / NS:g} s every {self.settings.step_period:g} s")
        self.presence = Presence(self, self._yield)     # last: a node that is fully up

    def _publisher(self, topic: T.Topic, qos=None):
        return self.create_publisher(topic.type, topic.name, T.writer_qos(qos or topic.qos))

    def _latched(self, topic: T.Topic):
        """A latched topic: the newest sample only, for late joiners too."""
        return self.create_publisher(topic.type, topic.name, topic.qos)

    def _tool_limits(self) -> ToolLimits:
        s = self.settings
        return ToolLimits(s.max_tool_speed, s.max_tool_accel, s.max_tool_jump)

    def _monitor_lead(self) -> MonitorLead:
        """Steps wait for the monitor's acknowledgements; a monitor silent for
        monitor_timeout is lost (the tool holds)."""
        s = self.settings
        return MonitorLead(s.monitor_lead, s.monitor_timeout)

    def _yield(self, reason: str) -> None:
        raise Yielded(reason)

    # -- one commander (the core's CommandGate) ----------------------------------------
    def _hold(self, reason: str, publish: bool = True) -> None:
        """Latch a hold: the tool stays where it is, set-points are ignored until ~/reset;
        the reason goes out on /shaping/abort (the planner stops, the monitor sees it)."""
        if not self.gate.hold(reason):
            return
        self.arrivals.clear()                   # nothing buffered is followed now
        tool = self.run.hold(self.timeline.t_ns)
        self.get_logger().error(f"the tool holds at ({tool[0] * 1e3:.3f}, {tool[1] * 1e3:.3f}) mm"
                                f" until ~/reset: {reason}")
        if publish:
            self.pub_abort.publish(String(data=f"simulator: {reason}"))
        self.cadence.force(diagnostics=True)            # the state and /diagnostics at once

    def _on_abort(self, msg: String) -> None:
        self._hold(f"abort: {msg.data}", publish=False)

    # -- parameters -------------------------------------------------------------------
    def _retune(self) -> None:
        """A tunable setting changed (after the build): the output schedule reads it."""
        self.cadence.settings = self.settings

    @property
    def cell(self) -> CellParams:
        return self.params["cell"]

    @property
    def settings(self) -> SimulatorNodeParams:
        return self.params["settings"]

    def _configure_time(self) -> None:
        s = self.settings
        self._sim_clock = s.real_time_factor != 1.0 or s.publish_clock
        self.timeline = SimClock(int(round(s.real_time_factor * s.step_period * NS)))
        if self._sim_clock:
            self.pub_clock = self._publisher(T.CLOCK)

    # -- the run (the core's SetpointRun) ---------------------------------------------
    def _new_run(self) -> None:
        """Settled sheet at process time 0, tool at the movement's start."""
        cell, s = self.cell, self.settings
        batch = batch_cell(cell, s.batch_k1, s.batch_c2, s.batch_mass,      # the batch played
                           s.batch_friction_mould if s.batch_friction_mould >= 0 else None,
                           s.batch_friction_tool if s.batch_friction_tool >= 0 else None)
        self.run = SetpointRun(batch, movement_scenario(cell).start)
        self._run_cell = cell
        self._tool_outline = tool_shape(cell.tool).outline(48)
        self._cake_outline = Cake.of(cell.cake).outline(48)
        self._commands_fresh = Freshness(self.settings.command_timeout)
        self.cadence.restart()
        self.pub_cell.publish(String(data=cell_message(cell)))

    @property
    def sim(self):
        """The core's :class:`~rheo_shaping.sheet.simulation.Simulation` of this run."""
        return self.run.sim

    @property
    def started(self) -> bool:
        return self.run.started

    @property
    def process_time(self) -> float:
        return self.run.process_time

    @property
    def process_offset_ns(self) -> int | None:
        """Process time 0 on the node (or simulated) clock [ns]; None before the start."""
        return self.run.offset_ns

    @property
    def peak(self):
        """F_max so far (:class:`~rheo_shaping.sheet.metrics.PeakTension`)."""
        return self.run.peak

    @property
    def history(self) -> list[tuple[float, float]]:
        """(process time [s], largest link tension [N]) of every step (for the cell runner)."""
        return self.run.history

    @property
    def summary(self):
        """The :class:`~rheo_shaping.sheet.metrics.RunSummary` once the process has ended."""
        return self.run.summary

    @property
    def lockstep_waits(self) -> int:
        return self.timeline.waits

    @property
    def monitor_waits(self) -> int:
        """Steps held back so far because the monitor had not judged the samples before."""
        return self._lead.waits

    def _on_reset(self, request, response):
        why = self._reset_refusal()
        if why:
            response.success, response.message = False, f"not reset: {why}"
            self.get_logger().warning(response.message)
            return response
        if self.gate.held:
            self.destroy_publisher(self.pub_abort)     # drops its latched abort sample
            self.pub_abort = self._latched(T.ABORT)
        self.gate.reset()
        self.arrivals.clear()
        self._new_run()
        response.success = True
        response.message = "run restarted: settled sheet at process time 0"
        self.get_logger().info(response.message)
        return response

    def _reset_refusal(self) -> str:
        """Why ~/reset may not re-arm now (core: MonitorLead.reset_refusal)."""
        trust = self._checked.trust()
        return self._lead.reset_refusal(self._steady.now().nanoseconds,
                                        trust.reason if trust.foreign else "", T.CHECKED.contract)

    # -- stepping ---------------------------------------------------------------------
    def _on_timer(self) -> None:
        if not self.presence.settled:
            return                      # an older simulator of this name would be known by then
        now = self._steady.now().nanoseconds
        if self._commander is None or now - self._commander_ns >= 0.5 * NS:
            self._commander_ns = now                # the graph asked twice a second at most
            self._say_commander()
        self._bind_waiting()
        lost = self._lead.lost_reason(self._steady.now().nanoseconds, bool(self.run.cmds),
                                      T.CHECKED.contract)
        if lost and not self.gate.held:
            self._hold(lost)
        self._pending = True
        self._try_step()

    def _try_step(self) -> None:
        if not self._pending:
            return
        s, clock = self.settings, self.timeline
        if self._sim_clock:
            target = clock.t_ns + clock.dt_ns
            tick = clock.tick(next_step(
                s.lockstep, s.start_on_command, self.run.started, clock.t_ns > 0,
                # a held tool is the safe state: the sheet settles under it without waiting
                # for a monitor that cannot judge (frozen, or refusing a rogue's samples)
                lambda: not self.gate.held and self._lead.behind(self._steady.now().nanoseconds),
                lambda: self.run.lacks_setpoint(target), bool(self.gate.held), self._stream_live),
                self._steady.now().nanoseconds)
            if tick.clock_ns is not None:
                self._publish_clock(tick.clock_ns)
            if tick.wait:       # re-tried on the next acknowledgement or set-point
                self._publish_steady(clock.t_ns)
                return
            if tick.step_to is None:            # /clock holds for the first set-point
                self._pending = False
                if tick.republish:
                    self._publish_state(clock.t_ns)    # the same state, fresh for the monitor
                self._hold_camera()
                self._publish_steady(clock.t_ns)
                return
            if tick.late:                       # the tool holds its last set-point
                self.get_logger().warning(
                    f"step to {target / NS:.3f} s without its set-point (newest "
                    f"{self.run.cmds[-1][0] / NS:.3f} s): the tool holds; late steps so far "
                    f"{clock.late_steps}", throttle_duration_sec=5.0)
        else:
            target = self.get_clock().now().nanoseconds
            if target <= clock.t_ns:
                return
        self._pending = False
        self._step_to(target)

    def _publish_clock(self, t_ns: int) -> None:
        """/clock at ``t_ns`` (only while this node is the clock, _configure_time)."""
        pub = self.pub_clock
        assert pub is not None
        pub.publish(m.clock_msg(t_ns))

    def _step_to(self, target: int) -> None:
        run, was_broken = self.run, self.run.broken
        finished, end_ns = run.step_to(target, self.settings.start_on_command)
        if finished is not None:
            self._finish(finished)
            if end_ns is not None:        # the state at the process end, then the run goes on
                self._publish_state(end_ns)
                run.advance(target)
            else:
                self.cadence.force()
        if run.broken and not was_broken:
            self.get_logger().error(f"the sheet solver failed at process time "
                                    f"{self.sim.state.t:.2f} s: {run.broken}; tensions are "
                                    f"published as NaN until ~/reset")
        self.timeline.t_ns = target
        self.run.prune(target)
        self._publish(target)

    def _finish(self, pt: float) -> None:
        s = self.summary
        self.get_logger().info(
            f"process time {pt:g} s reached: F_max = {s.F_max:.4f} N (link {s.F_max_link}, "
            f"t = {s.F_max_time:.1f} s), SF = {s.SF:.3f}, Delta = {s.delta * 1e3:.3f} mm "
            f"({self.timeline.late_steps} steps without their set-point)")


def main(args=None):
    return run_node(SimulatorNode, 'simulator', args)


if __name__ == '__main__':
    sys.exit(main())
