"""The managed (lifecycle) variants of the nodes: ``simulator_managed``, ``monitor_managed``,
``planner_managed``, ``gap_watch_managed`` (docs/ros.md, "Managed start-up").

Each is the plain node's class, unchanged, driven through the ROS 2 node lifecycle
(``rclpy.lifecycle``): the node starts ``unconfigured`` with only its lifecycle services and
its heartbeat; ``configure`` runs the plain node's construction (parameters, the settled sheet
or the plan, publishers, subscriptions, the safety checks), ``activate`` starts its timers (the
simulator steps, the monitor judges and beats ``/shaping/ready``, the planner supervises and
streams), ``deactivate`` stops them, ``cleanup`` destroys what ``configure`` made, ``shutdown``
ends in ``finalized``.  Every safety path is the plain node's: an abort, a hold, the command
gate and the clock guard act in every state the node has them (from ``configure`` on).

What each state means beyond that:

* simulator: ``deactivate`` first holds the tool (latched, the reason on ``/shaping/abort``);
* monitor: inactive, it still judges every tension sample it gets (and aborts on one), but
  does not report ready: ``/shaping/ready`` says false once and then stops; ``activate``
  starts its watch afresh (``startup_timeout`` counts from then) unless an abort is latched;
* planner: ``activate`` is refused unless the monitor reports ready (the interlock, as the
  planner sees it: a fresh ``/shaping/ready`` true from the one monitor); ``deactivate``
  while the tool moves stops it first (the plain planner's abort: a planned stop from the
  executed pose, sent to its end at rest), and no set-point goes out while it is inactive
  (state ``inactive``).

A heartbeat (``~/heartbeat``, std_msgs/String, JSON ``{"state", "transitions", "instance",
"latch"}``: the latch is the node's latched hold or abort, "" none) goes out every
:data:`~rheo_shaping.safety.lifecycle.HEARTBEAT_PERIOD` on the steady clock in every state:
the lifecycle manager tells a dead or frozen node by its silence (a killed process stays in
the DDS graph for its lease) and a held or aborted one by its latch.
"""
from __future__ import annotations

import json
import os
import sys
import time
from typing import Any, Callable

from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleNodeMixin, LifecycleState, TransitionCallbackReturn
from rclpy.node import Node
from std_msgs.msg import Bool, String

from ..params.schema import ParameterError
from ..safety.lifecycle_terms import HEARTBEAT_PERIOD
from ..params.wire import Field
from ..units import NS
from .hosts import ManagedMixin
from .gap_watch import GapWatchNode
from .monitor import MonitorNode
from .rclpy_private import clock_subscription, lifecycle_label, release_state_machine
from ..planning.states import MOVING
from .planner import PlannerNode
from .simulator import SimulatorNode
from . import topics as T
from .spin import run_node

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE

#: Longest latch reason a heartbeat carries [characters] (longer ones are cut).
LATCH_LEN = 400
#: A heartbeat's JSON keys as the lifecycle manager reads them (rheo_shaping.params.wire).
HEARTBEAT_FIELDS = {"state": Field(str, max_len=32), "transitions": Field(int, 0, 2**31),
                    "instance": Field(str, max_len=64), "latch": Field(str, max_len=LATCH_LEN)}


class Managed(LifecycleNodeMixin, ManagedMixin):
    """The lifecycle around the plain node class it is combined with: that class's ``_build``
    runs at ``configure``, its timers run only while ``active``."""

    def _managed_init(self, name: str, node_kwargs: dict, build_args: tuple) -> None:
        Node.__init__(self, name, **node_kwargs)
        LifecycleNodeMixin.__init__(self, enable_communication_interface=True)
        self._build_args = build_args
        self._work_timers: list | None = None   # the plain node's timers (from configure on)
        self._active = False
        self._transitions = 0
        self._instance = f"{os.getpid()}-{time.time_ns()}"
        self._hb_steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._hb_pub = self.create_publisher(T.HEARTBEAT.type, T.HEARTBEAT.name, T.HEARTBEAT.qos)
        self.create_timer(HEARTBEAT_PERIOD, self._beat, clock=self._hb_steady)
        self._base = self._entities()
        self.get_logger().info("unconfigured: waiting for configure (lifecycle_manager, or "
                               "`ros2 lifecycle set`)")

    def destroy_node(self) -> None:
        """Node.destroy_node, and the lifecycle state machine, which holds the node's handle
        (rclpy leaves it: the node would stay in the graph, where a new node of its name
        waits for it to leave, nodes.guards.Presence)."""
        Node.destroy_node(self)
        release_state_machine(self)

    # -- heartbeat ----------------------------------------------------------------
    @property
    def lifecycle_state(self) -> str:
        """The primary state's label (unconfigured, inactive, active, finalized)."""
        return lifecycle_label(self)

    def _beat(self) -> None:
        self._hb_pub.publish(String(data=json.dumps(
            {"state": self.lifecycle_state, "transitions": self._transitions,
             "instance": self._instance, "latch": self._latch()[:LATCH_LEN]})))

    def _latch(self) -> str:
        """The node's latched hold or abort ("" none, and before configure)."""
        return ""

    # -- the plain node's timers run only while active ----------------------------
    def create_timer(self, *args, **kwargs):
        timer = Node.create_timer(self, *args, **kwargs)
        if self._work_timers is not None:
            self._work_timers.append(timer)
            if not self._active:
                timer.cancel()
        return timer

    def destroy_timer(self, timer) -> bool:
        if self._work_timers is not None and timer in self._work_timers:
            self._work_timers.remove(timer)
        return Node.destroy_timer(self, timer)

    def _run_timers(self, run: bool) -> None:
        for timer in self._work_timers or ():
            timer.reset() if run else timer.cancel()

    # -- entities made by configure -----------------------------------------------
    def _entities(self) -> dict[str, set[int]]:
        return {kind: {id(e) for e in getattr(self, kind)}
                for kind in ("publishers", "subscriptions", "services", "clients", "timers",
                             "guards")}

    def _destroy_built(self) -> None:
        """Destroy every entity made since the lifecycle's own (the plain node's), but the
        time source's /clock subscription (guard_clock made it again; the node keeps it),
        after the plain node's own work has ended (:meth:`_end_work`)."""
        self._end_work()
        keep = clock_subscription(self)
        destroy: dict[str, Callable[[Any], object]] = {
                   "publishers": self.destroy_publisher,
                   "subscriptions": self.destroy_subscription,
                   "services": self.destroy_service, "clients": self.destroy_client,
                   "timers": self.destroy_timer, "guards": self.destroy_guard_condition}
        for kind, method in destroy.items():
            for entity in list(getattr(self, kind)):
                if id(entity) not in self._base[kind] and entity is not keep:
                    method(entity)
        params = getattr(self, "params", None)
        if params is not None:
            self.remove_on_set_parameters_callback(params._validate)
            self.remove_post_set_parameters_callback(params._changed)
            for name in params.fields:
                if self.has_parameter(name):
                    self.undeclare_parameter(name)
            del self.params
        self._work_timers = None

    # -- transitions ----------------------------------------------------------------
    def _done(self, result: TransitionCallbackReturn, what: str) -> TransitionCallbackReturn:
        if result == SUCCESS:
            self._transitions += 1
            self.get_logger().info(what)
        return result

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._work_timers = []
        try:
            self._build(*self._build_args)
        except ParameterError as exc:
            self.get_logger().error(f"configure refused: {exc}")
            self._destroy_built()
            return FAILURE
        self._run_timers(False)
        return self._done(SUCCESS, "configured (inactive)")

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        why = self._may_activate()
        if why:
            self.get_logger().warning(f"activate refused: {why}")
            return FAILURE
        self._active = True
        self._on_activated()
        self._run_timers(True)
        return self._done(SUCCESS, "active")

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop()
        return self._done(SUCCESS, "deactivated (inactive)")

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._destroy_built()
        return self._done(SUCCESS, "cleaned up (unconfigured)")

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop()
        if self._work_timers is not None:
            self._destroy_built()
        return self._done(SUCCESS, "shut down (finalized)")

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.get_logger().error(f"a transition from {state.label} raised: what it built is "
                                f"stopped (as by deactivate) and destroyed; back to unconfigured")
        self._stop()
        if self._work_timers is not None:
            self._destroy_built()
        return SUCCESS

    def _stop(self) -> None:
        """What deactivate does (nothing when not active): the node's own safe stop, then
        its timers."""
        if self._active:
            self._on_deactivating()
            self._active = False
            self._run_timers(False)

    # -- what each node adds --------------------------------------------------------
    def _end_work(self) -> None:
        """End what the plain node runs beside its executor (threads, processes)."""

    def _may_activate(self) -> str:
        return ""

    def _on_activated(self) -> None:
        pass

    def _on_deactivating(self) -> None:
        pass


class ManagedSimulatorNode(Managed, SimulatorNode):
    """The simulator as a lifecycle node: it steps only while active; deactivate holds the
    tool first."""

    def __init__(self, message_info: bool = True, **node_kwargs):
        self._managed_init('simulator', node_kwargs, (node_kwargs, message_info))

    def _on_deactivating(self) -> None:
        self._hold("deactivated (lifecycle): the tool holds")

    def _latch(self) -> str:
        gate = getattr(self, "gate", None)
        return gate.held if gate is not None else ""


class ManagedMonitorNode(Managed, MonitorNode):
    """The monitor as a lifecycle node: ready only while active."""

    def __init__(self, **node_kwargs):
        self._managed_init('monitor', node_kwargs, (node_kwargs,))

    def _on_activated(self) -> None:
        if self.state != "aborted":
            self._clear()           # a fresh watch: startup_timeout counts from now

    def _on_deactivating(self) -> None:
        self.pub_ready.publish(Bool(data=False))

    def _latch(self) -> str:
        return self.abort_reason if getattr(self, "core", None) is not None else ""


class ManagedPlannerNode(Managed, PlannerNode):
    """The planner as a lifecycle node: activates only behind the monitor's interlock,
    streams only while active."""

    def __init__(self, **node_kwargs):
        self._managed_init('planner', node_kwargs, (node_kwargs,))

    def _may_activate(self) -> str:
        ok, why = self._monitor_ok()
        return "" if ok else f"the interlock: {why}"

    def _latch(self) -> str:
        return self.abort_reason if getattr(self, "aborted", False) else ""

    def _on_deactivating(self) -> None:
        if self.streamer is not None and self.streamer.state in MOVING:
            if self.aborted:
                # an abort latched before (its stop sent, now retracting): the retract is
                # stopped too, or the stream would stay `retracting` while inactive and
                # refuse the recovery's ~/reset ("the tool is moving")
                self._stop_run("planner: deactivated (lifecycle)")
            else:
                self._abort("planner: deactivated (lifecycle)")     # the planned stop
            self.streamer.hold_after_stop()     # an inactive planner streams no retract
            self._send_stop()
        self._set_state("inactive")

    def _send_stop(self) -> None:
        """The rest of the stop at once, to its end at rest (max_lead bounds how far ahead a
        stream may run so that a later abort can stop from the executed pose; an inactive
        planner has no later abort).  The simulator follows it in lockstep, its command gate
        checking every set-point; the retract after it is not sent."""
        st = self.streamer
        if st is None or st.stop_plan is None or st.abort_time is None or self.grid is None:
            return
        end = int(round((st.abort_time + st.stop_plan.duration) * NS))
        for t in self.grid.due(end, end, True):
            self._publish_setpoint(t)

    def _stream(self) -> None:
        if self._active:
            PlannerNode._stream(self)

    def _abort(self, reason: str) -> None:
        """An abort while inactive (the simulator's own deactivation, a monitor's) latches
        only: a stop begun then would never be streamed, and the stream would stay moving
        and refuse the recovery's ~/reset."""
        if self._active:
            PlannerNode._abort(self, reason)
        elif self.latch.abort(reason):
            self.get_logger().warning(f"abort while inactive ({reason}): latched, nothing "
                                      f"moves (~/reset to re-arm)")
            self._update_state()


class ManagedGapWatchNode(Managed, GapWatchNode):
    """The gap watch as a lifecycle node: it publishes its residuals, states and verdicts
    only while active (its model's worker runs from configure to cleanup)."""

    def __init__(self, **node_kwargs):
        self._managed_init('gap_watch', node_kwargs, (node_kwargs,))

    def _end_work(self) -> None:
        GapWatchNode._end_work(self)

    def destroy_node(self) -> None:
        self._end_work()
        Managed.destroy_node(self)


def simulator_main(args=None):
    return run_node(ManagedSimulatorNode, 'simulator', args)


def monitor_main(args=None):
    return run_node(ManagedMonitorNode, 'monitor', args)


def planner_main(args=None):
    return run_node(ManagedPlannerNode, 'planner', args)


def gap_watch_main(args=None):
    return run_node(ManagedGapWatchNode, 'gap_watch', args)


if __name__ == '__main__':  # pragma: no cover - python -m rheo_shaping.nodes.managed NODE
    mains = {"simulator": simulator_main, "monitor": monitor_main, "planner": planner_main,
             "gap_watch": gap_watch_main}
    name = sys.argv.pop(1) if len(sys.argv) > 1 else ""
    if name not in mains:
        sys.exit("usage: python -m rheo_shaping.nodes.managed "
                 "simulator|monitor|planner|gap_watch ...")
    sys.exit(mains[name]())
