"""The planner's states, as it reports them on ``/shaping/planner_state``: the one
vocabulary that the planner node, its stream (:class:`~rheo_shaping.planning.stopping.
TrajectoryStreamer`), the monitor's acknowledgements, the recorder and the cell read.
No ROS imports here."""
from __future__ import annotations

#: The states of a plan's stream (:class:`~rheo_shaping.planning.stopping.TrajectoryStreamer`).
STREAM_STATES = ("idle", "running", "stopping", "retracting", "holding", "done")
#: States of a planner whose tool moves: it leaves them only through a stop (holding,
#: done, error), never back to a state before a run.
MOVING = ("running", "stopping", "retracting")
#: States of a planner at rest after a run (its plan done, or held after a stop).
AT_REST = ("done", "holding")
#: States of a planner node that has not started a plan: starting up, idle (autostart off),
#: waiting (autostart on, or a check), and what
#: :func:`~rheo_shaping.planning.run_state.start_decision` waits for or refuses.
BEFORE_RUN = ("starting", "idle", "waiting", "waiting_for_pose", "tool_away",
              "waiting_for_monitor", "waiting_for_cell", "waiting_for_clock",
              "waiting_for_subscriber")
#: Every state a planner reports (``error``: it could not start, ~/reset; ``inactive``: a
#: managed planner deactivated, rheo_shaping.nodes.managed).
PLANNER_STATES = tuple(dict.fromkeys(BEFORE_RUN + STREAM_STATES + ("error", "inactive")))
