"""The hosts of the nodes' mixins, as :class:`typing.Protocol` classes: what each mixin
uses of the node it is mixed into (attributes and methods the node defines, or a sibling
mixin), with their types.  The node's state a mixin sets is declared in the mixin's body
(the node initializes it); a mixin's own attributes and methods stay in the mixin.

A mixin is typed against its host: for mypy only, it derives from its protocol and from
rclpy's ``Node`` (:data:`PlannerMixin`, :data:`SimulatorMixin`, :data:`ManagedMixin`; at
run time their base is ``object``), so its code is checked against the declarations here
and the node's own definitions are checked against the same declarations where the node
overrides them; mypy refuses to make a node that lacks a method or attribute declared
here (an abstract member of its base).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Protocol

if TYPE_CHECKING:
    import numpy as np
    from rclpy.clock import Clock
    from rclpy.node import Node
    from rclpy.publisher import Publisher
    from rclpy.subscription import Subscription

    from ..params.cell import CellParams
    from ..params.node_params import PlannerNodeParams, SimulatorNodeParams
    from ..planning.plans import MotionLimits, Plan
    from ..planning.run_state import RunLatch, SetpointGrid
    from ..planning.stopping import TrajectoryStreamer
    from ..safety.acknowledge import MonitorLead
    from ..safety.command_gate import CommandGate
    from ..safety.watchdog import Freshness
    from ..sheet.metrics import PeakTension, RunSummary
    from ..sheet.setpoints import SetpointRun, SimClock
    from ..sheet.simulation import Simulation
    from .guards import OwnedStream, Presence
    from .ros_params import SchemaParameters


class PlannerHost(Protocol):
    """The planner node as :class:`~.planner_supervision.PlannerSupervision` and
    :class:`~.planner_adaptive.PlannerAdaptive` use it (:class:`~.planner.PlannerNode`)."""

    # parameters, plan and publishers
    @property
    def settings(self) -> PlannerNodeParams: ...
    cell_used: CellParams
    plan: Plan
    pub_trajectory: Publisher
    presence: Presence
    _steady: Clock
    # the run
    streamer: TrajectoryStreamer | None
    grid: SetpointGrid | None
    latch: RunLatch
    _ready_rx: int | None
    _ready_topic: str
    # the executed tool
    _tool_pose: np.ndarray | None
    _pose_ns: int | None

    @property
    def _t0_ns(self) -> int | None: ...
    @property
    def _last_cmd_ns(self) -> int | None: ...
    def _now_ns(self) -> int: ...
    def _monitor_ok(self) -> tuple[bool, str]: ...
    def _tool_away(self) -> str: ...
    def _refusal(self) -> str: ...
    def _abort(self, reason: str) -> None: ...
    def _set_state(self, state: str) -> None: ...
    def _plan_from(self, start_xz: Any) -> Plan: ...
    def _retract_limits(self) -> MotionLimits: ...
    def _stream(self) -> None: ...
    def _adaptive_plan(self, plan: Plan) -> Plan: ...      # PlannerAdaptive's
    def _adaptive_waits(self) -> bool: ...                  # PlannerAdaptive's


class SimulatorHost(Protocol):
    """The simulator node as :class:`~.simulator_intake.SetpointIntake` and
    :class:`~.simulator_outputs.SimulatorOutputs` use it (:class:`~.simulator.SimulatorNode`)."""

    @property
    def settings(self) -> SimulatorNodeParams: ...
    _steady: Clock
    # the run (the core's SetpointRun) and the cell it runs
    run: SetpointRun
    _run_cell: CellParams
    timeline: SimClock              # its simulated time and the step policy's counts
    _pending: bool
    _sim_clock: bool

    @property
    def sim(self) -> Simulation: ...
    @property
    def started(self) -> bool: ...
    @property
    def summary(self) -> RunSummary | None: ...
    @property
    def peak(self) -> PeakTension: ...
    # set-points in: the gate, the streams it trusts
    gate: CommandGate
    _command_sub: Subscription
    _commands_fresh: Freshness
    _checked: OwnedStream
    _lead: MonitorLead

    def _hold(self, reason: str, publish: bool = True) -> None: ...
    def _try_step(self) -> None: ...
    # what goes out
    pub_commander: Publisher
    pub_profile: Publisher
    pub_tensions: Publisher
    pub_contact: Publisher
    pub_pose: Publisher
    pub_wrench: Publisher
    pub_markers: Publisher
    pub_diag: Publisher
    pub_camera: Publisher
    _camera_rng: np.random.Generator
    _tool_outline: np.ndarray
    _cake_outline: np.ndarray


class ManagedHost(Protocol):
    """The plain node a :class:`~.managed.Managed` lifecycle is combined with."""

    #: the plain node's construction (run at ``configure``)
    _build: Callable[..., None]
    #: its parameters (from ``configure`` on; ``cleanup`` undeclares them)
    params: SchemaParameters


if TYPE_CHECKING:
    class PlannerMixin(PlannerHost, Node):
        """A planner mixin's base for mypy: its host protocol and rclpy's Node."""

    class SimulatorMixin(SimulatorHost, Node):
        """A simulator mixin's base for mypy: its host protocol and rclpy's Node."""

    class ManagedMixin(ManagedHost, Node):
        """:class:`~.managed.Managed`'s base for mypy: its host protocol and rclpy's Node."""
else:
    PlannerMixin = SimulatorMixin = ManagedMixin = object
