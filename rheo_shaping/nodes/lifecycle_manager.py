"""The ``lifecycle_manager`` node: brings a managed cell up in order and down to a safe state
when one of its nodes fails (docs/ros.md, "Managed start-up"), in the style of Nav2's.

It drives the nodes of its ``node_names`` in its own namespace (``simulator``, ``monitor``,
``planner``, and ``gap_watch`` when named; the managed executables ``*_managed``,
rheo_shaping.nodes.managed) through their lifecycle services
(``<node>/change_state``, lifecycle_msgs/ChangeState).  What to ask and when is the core's
:class:`~rheo_shaping.safety.lifecycle.CellLifecycle`: configure all, activate simulator and
monitor, the planner once the monitor reports ready; on a failure (a node's ``~/heartbeat``
silent for ``heartbeat_timeout``, a node that left ``active``, a failed transition) the
reason goes out on ``shaping/abort`` (the simulator holds the tool, the planner stops) and
the planner is deactivated.  ``~/status`` (JSON, latched) and ``/diagnostics`` say the phase,
the reason and what it waits for.  ``~/manage_nodes`` (lifecycle_msgs/ChangeState, the
command in the transition's label) takes Nav2's commands: startup, pause, resume, reset,
shutdown (:data:`~rheo_shaping.safety.lifecycle.COMMANDS`; a client:
:class:`~rheo_shaping.nodes.manager_client.LifecycleManagerClient`); ``~/is_active``
(std_srvs/Trigger) is Nav2's query.  ``~/startup`` and ``~/shutdown`` (std_srvs/Trigger) bring
the cell up again (after a failure or a hold: restart a lost node first; ``~/startup`` then
configures and activates it and clears every node's latch in order, rheo_shaping.safety.
lifecycle) or down (deactivate in reverse order, then clean up).
"""
from __future__ import annotations

import sys
from functools import partial
from typing import cast

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from ..params.manager_params import LifecycleManagerParams
from ..safety.lifecycle import CellLifecycle
from ..safety.lifecycle_terms import Step
from ..safety.clock_guard import ClockGuard
from ..safety.manager import Reply, Requests, cell_status
from ..safety.watchdog import StallGuard
from ..params.wire import WireError, read_fields
from ..units import NS
from . import messages as m
from . import topics as T
from .guards import OwnedStream, guard_clock
from .managed import HEARTBEAT_FIELDS
from .ros_params import SchemaParameters
from .spin import build_or_destroy, run_node


#: What the manager did with a request its node shows no sign of (Requests.unheard).
UNHEARD = {"resend": "sent again, lost before its service matched",
           "remake": "its service is not seen while the node beats: its clients made again"}
#: Largest forward jump [s] of /clock the manager applies (the nodes' max_clock_jump default).
MANAGER_CLOCK_JUMP = 5.0


class LifecycleManagerNode(Node):
    """Brings the managed cell of its namespace up and keeps it safe."""

    def __init__(self, **node_kwargs):
        super().__init__('lifecycle_manager', **node_kwargs)
        build_or_destroy(self, self._build, node_kwargs)

    def _build(self, node_kwargs: dict) -> None:
        self.params = SchemaParameters(self, {"settings": LifecycleManagerParams},
                                       cli_args=node_kwargs.get('cli_args'))
        s = self.settings
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.nodes = s.nodes                # node_names, in the order they come up
        self.core = CellLifecycle(heartbeat_timeout=s.heartbeat_timeout,
                                  ready_timeout=s.heartbeat_timeout, nodes=self.nodes)
        self._change_state: dict = {}       # each node's change_state client
        self._reset: dict = {}              # each node's ~/reset (a recovery clears latches)
        self.requests = Requests(s.transition_timeout)   # asked, sent, out of time (core)
        # each heartbeat only from its node, /shaping/ready only from the monitor
        # (by name: a restarted node beats while the killed one's writer is in the graph)
        self._beat_src = {name: OwnedStream(self, f"{name}/heartbeat", name, strict=False)
                          for name in self.nodes}
        self._ready_src = OwnedStream(self, T.READY.name, "monitor")
        for name in self.nodes:
            self.create_subscription(T.HEARTBEAT.type, f"{name}/heartbeat",
                                     partial(self._on_heartbeat, name),
                                     T.HEARTBEAT.qos)
            self._clients_of(name)
        self.create_subscription(T.READY.type, T.READY.name, self._on_ready, T.READY.qos)
        self.pub_abort = self.create_publisher(T.ABORT.type, T.ABORT.name, T.ABORT.qos)
        self.pub_status = self.create_publisher(T.MANAGER_STATUS.type, T.MANAGER_STATUS.name,
                                                T.MANAGER_STATUS.qos)
        self.pub_diag = self.create_publisher(T.DIAGNOSTICS.type, T.DIAGNOSTICS.name,
                                              T.DIAGNOSTICS.qos)
        self.create_service(Trigger, '~/startup', self._on_startup)
        self.create_service(Trigger, '~/shutdown', self._on_shutdown)
        self.create_service(Trigger, '~/is_active', self._on_is_active)
        # Nav2's one manage service: the command in the transition's label (COMMANDS)
        self.create_service(ChangeState, '~/manage_nodes', self._on_manage_nodes)
        self._guard = StallGuard(0.5 * s.heartbeat_timeout)
        # on the cell's clock (use_sim_time) its /diagnostics stamps are the cell's; a
        # refused /clock (a forged jump, a negative time) is not applied, only logged: the
        # manager's checks run on the steady clock
        guard_clock(self, ClockGuard(MANAGER_CLOCK_JUMP), lambda why: self.get_logger().error(
            f"/clock refused: {why}", throttle_duration_sec=5.0))
        self._status = ""
        self._last_diag: int | None = None
        if s.autostart:
            self.core.startup()
        self.create_timer(s.period, self._tick, clock=self._steady)
        self.get_logger().info(
            f"lifecycle manager up: {', '.join(self.nodes)} in "
            f"{self.get_namespace()}; heartbeat_timeout {s.heartbeat_timeout:g} s"
            + ("" if s.autostart else "; waiting for ~/startup"))

    @property
    def settings(self) -> LifecycleManagerParams:
        return self.params["settings"]

    # -- observations ---------------------------------------------------------------
    def _on_heartbeat(self, name: str, msg: String) -> None:
        trust = self._beat_src[name].trust()
        if not trust.trusted:
            return            # another writer's beat never stands for the node (logged once)
        try:
            beat = read_fields(msg.data, HEARTBEAT_FIELDS)
        except WireError as exc:
            self.get_logger().warning(f"{name}/heartbeat: not a heartbeat ({exc}): "
                                      f"{msg.data[:80]!r}", throttle_duration_sec=5.0)
            return
        self.core.heartbeat(name, beat["state"], self._steady.now().nanoseconds,
                            beat["transitions"], beat["instance"], beat["latch"])

    def _on_ready(self, msg: Bool) -> None:
        if self._ready_src.trust().trusted:
            self.core.monitor_ready(msg.data, self._steady.now().nanoseconds)

    # -- services -------------------------------------------------------------------
    def _on_startup(self, request, response):
        why = self.core.startup()
        if not why:
            self._drop_latched_abort()
        response.success, response.message = not why, why or "bringing the cell up"
        self.get_logger().info(f"~/startup: {response.message}")
        return response

    def _on_manage_nodes(self, request, response):
        """Nav2's manage_nodes: ``request.transition.label`` one of startup, pause, resume,
        reset, shutdown (rheo_shaping.safety.lifecycle.COMMANDS); the reason of a refusal in
        the log and on ~/status."""
        command = request.transition.label
        why = self.core.command(command)
        if not why and command in ("startup", "resume"):
            self._drop_latched_abort()
        response.success = not why
        self.get_logger().info(f"~/manage_nodes {command!r}: {why or 'done'}")
        return response

    def _drop_latched_abort(self) -> None:
        """The abort this manager latched (a failure) is dropped: late joiners do not get
        it."""
        self.destroy_publisher(self.pub_abort)
        self.pub_abort = self.create_publisher(T.ABORT.type, T.ABORT.name, T.ABORT.qos)

    def _on_is_active(self, request, response):
        """Nav2's query: success only while the cell is active (the tool can move)."""
        response.success = self.core.phase == "active"
        response.message = self.core.phase + (f": {self.core.reason}" if self.core.reason
                                              else "")
        return response

    def _on_shutdown(self, request, response):
        why = self.core.shutdown()
        response.success, response.message = not why, why or "bringing the cell down"
        self.get_logger().info(f"~/shutdown: {response.message}")
        return response

    # -- the checks (steady clock) --------------------------------------------------
    def _tick(self) -> None:
        now = self._steady.now().nanoseconds
        stalled = self._guard.check(now)
        self._collect(now)
        was = self.core.phase
        for step in self.core.steps(now, self._guard.previous if stalled else None):
            self._do(step, now)
        for name, transition in self.core.unheard(now):
            what = self.requests.unheard(name, now, self._drop)       # core: Requests
            if what == "remake":
                self._clients_of(name)
            if what:
                self.get_logger().warning(f"{transition} {name}: its heartbeat shows no sign of "
                                          f"the request ({what}: {UNHEARD[what]})")
        self._collect(now)                      # the new requests sent at once if they can
        if self.core.phase == "failed" and was != "failed":
            self.get_logger().error(f"the cell failed: {self.core.reason}; the tool holds, the "
                                    f"planner is deactivated")
        elif self.core.phase != was:
            self.get_logger().info(f"cell {self.core.phase}")
        waiting = self.core.waiting_for(now)
        if waiting:
            self.get_logger().info(f"waiting for {waiting}", throttle_duration_sec=5.0)
        self._publish_status(waiting, now)

    def _do(self, step: Step, now: int) -> None:
        if step.action == "hold":
            self.pub_abort.publish(String(data=f"lifecycle_manager: {step.reason}"))
            return
        self.get_logger().info(f"{step.action} {step.node}")
        self.requests.ask(step.node, step.action, now)

    def _clients_of(self, name: str) -> None:
        """(Re)make ``name``'s ``change_state`` and ``reset`` clients."""
        for clients in (self._change_state, self._reset):
            old = clients.pop(name, None)
            if old is not None:
                self.destroy_client(old)
        self._change_state[name] = self.create_client(ChangeState, f"{name}/change_state")
        self._reset[name] = self.create_client(Trigger, f"{name}/reset")

    def _client(self, name: str, transition: str):
        return (self._reset if transition == "reset" else self._change_state)[name]

    def _call(self, name: str, transition: str) -> Future:
        request = (Trigger.Request() if transition == "reset"
                   else ChangeState.Request(transition=Transition(label=transition)))
        return self._client(name, transition).call_async(request)

    def _drop(self, name: str, transition: str, future: Reply) -> None:
        self._client(name, transition).remove_pending_request(cast(Future, future))

    def _collect(self, now: int) -> None:
        """Requests whose service showed up, replies that came, those out of time (core)."""
        for a in self.requests.collect(
                now, lambda name, tr: self._client(name, tr).service_is_ready(), self._call,
                self._drop):
            self.core.answered(a.node, a.transition, a.ok, a.why,
                               steady_ns=now if a.replied else None)   # a reply is a beat

    def _publish_status(self, waiting: str, now: int) -> None:
        text, level, message, values = cell_status(
            self.core.phase, self.core.reason, waiting,
            {n: s.state for n, s in self.core.seen.items()})
        if text != self._status:
            self._status = text
            self.pub_status.publish(String(data=text))
        if self._last_diag is None or now - self._last_diag >= NS:
            self._last_diag = now
            name = m.status_name(self.get_namespace(), "lifecycle_manager")
            self.pub_diag.publish(m.diagnostics_msg(self.get_clock().now().nanoseconds,
                                                    name, level, message, values,
                                                    m.hardware_id(self.get_namespace())))


def main(args=None):
    return run_node(LifecycleManagerNode, 'lifecycle_manager', args, warm=False)  # no sheet


if __name__ == '__main__':
    sys.exit(main())
