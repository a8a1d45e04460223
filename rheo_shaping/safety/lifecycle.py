"""The managed cell's decisions without ROS (docs/ros.md, "Managed start-up"): what the
lifecycle manager does and when (its words: :mod:`.lifecycle_terms`), decided by
:class:`CellLifecycle` from what it has observed:

each node's heartbeat (``~/heartbeat``: its primary state, every :data:`HEARTBEAT_PERIOD`
on its steady clock) with the time it arrived, the monitor's ``/shaping/ready``, and the
replies to the transitions it asked for.

Bring-up (``startup``): configure every node in :data:`CELL_ORDER` (simulator, monitor,
planner), then activate them in the same order; the planner only once the monitor is
``active`` and reports ready (:func:`interlock_refusal`; the planner's ``on_activate`` asks
the same of its own view).  Bring-down (``shutdown``): deactivate in reverse, then clean up.

A failure: a node whose heartbeat stops for longer than ``heartbeat_timeout`` (a process that
died or froze; a killed process stays in the DDS graph for its lease, ~20 s, so the heartbeat
is what tells), a node that leaves ``active`` without being asked, or a transition that failed
brings the cell to its safe state at once: the tool holds (an abort with the reason on
``/shaping/abort``, which the simulator follows by holding the tool and the planner by
stopping) and the planner is deactivated.  The failure latches with its reason until the
next ``startup``.

The manager's ``active`` means the tool can move: a latched hold, abort or refusal that a
node reports in its heartbeat (``latch``: the simulator's hold, the monitor's or the
planner's abort) takes an active cell to ``held`` with that node's reason, and back to
``active`` once every latch has cleared.  ``startup`` after a failure or a hold recovers the
cell through the manager alone: a restarted (unconfigured) node is configured and activated,
then every latch is cleared in :data:`RESET_ORDER` (each node's ``~/reset``: the monitor
re-armed first, then the simulator's hold, then the planner), and the planner is activated
behind the interlock.  Times are steady-clock nanoseconds.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..units import NS
from .lifecycle_terms import (ACTIVATE_RETRIES, ACTIVE, CELL_ORDER, COMMANDS, FINALIZED,
                              HEARTBEAT_PERIOD, INACTIVE, INTERLOCK, RESET_ORDER,
                              RESET_RETRIES, RESET_RETRY_S, TRANSITIONS, UNCONFIGURED,
                              UNHEARD_S, NodeSeen, Step, interlock_refusal)


@dataclass
class CellLifecycle:
    """The lifecycle manager's state machine: phases ``idle`` -> ``starting`` -> ``active``;
    ``active`` <-> ``held`` (a node's latch, :attr:`reason` names it); ``pausing`` ->
    ``paused`` (every node deactivated: the tool holds); ``stopping`` -> ``down`` (and
    cleaned up); ``finalizing`` -> ``finalized`` (shut down: the processes must be started
    again); ``failed`` (latched with :attr:`reason`) from ``starting``, ``active`` or
    ``held``.  Feed it observations, ask :meth:`steps` what to do; Nav2's commands
    (:data:`COMMANDS`) are :meth:`command`."""

    heartbeat_timeout: float                       # [s] silence that counts as a lost node
    ready_timeout: float = 1.0                     # [s] age beyond which /shaping/ready is old
    nodes: tuple[str, ...] = CELL_ORDER
    phase: str = "idle"
    reason: str = ""                               # why the cell failed ("" while it has not)
    seen: dict[str, NodeSeen] = field(default_factory=dict)
    _ready: tuple[bool, int | None] = (False, None)
    _hold_due: bool = False                        # the failure's hold is still to be sent
    _resets: list[str] = field(default_factory=list)   # latches a recovery still clears
    _reset_refused: tuple[int, int, str] = (0, 0, "")  # refusals, retry time [ns], why
    _steady_ns: int = 0                            # the time of the newest check [ns]
    _relatched_n: tuple[int, int] = (0, 0)         # latches cleared again, next time [ns]

    def __post_init__(self) -> None:
        if self.heartbeat_timeout <= HEARTBEAT_PERIOD:
            raise ValueError(f"heartbeat_timeout {self.heartbeat_timeout:g} s: expected more "
                             f"than the heartbeat period {HEARTBEAT_PERIOD:g} s")
        for name in self.nodes:
            self.seen.setdefault(name, NodeSeen())

    # -- observations --------------------------------------------------------------
    def heartbeat(self, node: str, state: str, steady_ns: int, transitions: int = 0,
                  instance: str = "", latch: str = "") -> None:
        """``node`` (process ``instance``) reported its primary ``state`` after
        ``transitions`` completed transitions, and its latched hold or abort (``latch``, ""
        none).  A beat sent before the reply to a transition asked of the same process
        (fewer transitions than the reply implies) is old news: only its time counts."""
        seen = self.seen.get(node)
        if seen is None:
            return
        seen.beat_ns = steady_ns
        seen.latch = latch
        seen.heard = (instance, state, transitions)
        if (instance == seen.instance and seen.pending in TRANSITIONS
                and seen.refusal is not None and transitions <= seen.asked_at
                and steady_ns > seen.refusal[1]):
            # a re-sent request refused, and the node did not do it before: refused
            self.answered(node, seen.pending, False, seen.refusal[0], final=True)
            return
        if (instance == seen.instance and seen.pending in TRANSITIONS
                and transitions > seen.asked_at):
            # the transition asked for is done, its reply not here (lost or late): the beat
            # tells its outcome
            self.answered(node, seen.pending, state == TRANSITIONS[seen.pending],
                          f"the node reports {state}")
            return
        if instance == seen.instance and (seen.pending or transitions < seen.transitions):
            return
        seen.state, seen.instance, seen.transitions = state, instance, transitions

    def monitor_ready(self, ready: bool, steady_ns: int) -> None:
        """A ``/shaping/ready`` heartbeat."""
        self._ready = (bool(ready), steady_ns)

    def answered(self, node: str, transition: str, success: bool, message: str = "",
                 steady_ns: int | None = None, final: bool = False) -> None:
        """The reply to the ``transition`` of ``node`` asked for (False: refused, failed or
        not answered in time), received at ``steady_ns`` (a reply is a sign of life too).
        A refusal of a request sent again (:meth:`unheard`) may be the node's answer to a
        duplicate of one it carried out (its reply lost): it is judged with the node's next
        heartbeat (``final``: judged)."""
        seen = self.seen[node]
        if seen.pending != transition:
            return                     # answered already (by a heartbeat): a late reply
        if (not success and seen.resent and not final and transition in TRANSITIONS
                and steady_ns is not None):
            seen.refusal = (message, steady_ns)
            return
        seen.pending, seen.resent, seen.refusal = "", 0, None
        if steady_ns is not None:
            seen.beat_ns = max(seen.beat_ns or steady_ns, steady_ns)
        if transition == "reset":
            why = f"the {node} refused its reset" + (f": {message}" if message else "")
            refused = self._reset_refused[0] + 1
            if success:
                seen.latch = ""        # (its next beat says so too)
                self._resets.remove(node)
                self._reset_refused = (0, 0, "")
            elif self.phase == "starting" and refused < RESET_RETRIES:
                retry = (steady_ns or 0) + int(RESET_RETRY_S * NS)
                self._reset_refused = (refused, retry, why)
            elif self.phase == "starting":
                self._fail(f"{why} ({refused} times)")
            return
        if success:
            seen.state, seen.refused = TRANSITIONS[transition], 0
            seen.transitions = seen.asked_at + 1
            return
        why = f"{transition} of the {node} failed" + (f": {message}" if message else "")
        if (transition == "activate" and node == INTERLOCK[1] and self.phase == "starting"
                and seen.refused + 1 < ACTIVATE_RETRIES):
            seen.refused += 1          # tried again once the interlock allows (steps)
        elif self.phase in ("starting", "active"):
            self._fail(why)
        elif self.phase in ("stopping", "pausing", "finalizing"):
            self.reason = why           # noted; the bring-down goes on with the others

    def command(self, name: str) -> str:
        """One of Nav2's commands (:data:`COMMANDS`: startup, pause, resume, reset, shutdown);
        "" or why not now."""
        if name not in COMMANDS:
            return f"unknown command {name!r}: expected one of {', '.join(COMMANDS)}"
        return {"startup": self.startup, "pause": self.pause, "resume": self.startup,
                "reset": self.shutdown, "shutdown": self.finalize}[name]()

    def startup(self) -> str:
        """Bring the cell up (again after a failure, a hold, a pause or a bring-down: every
        node's latch is cleared in :data:`RESET_ORDER` on the way); "" or why not now."""
        if self.phase in ("starting", "active"):
            return f"already {self.phase}"
        if self.phase in ("finalizing", "finalized"):
            return f"the cell is {self.phase}: start its processes again"
        if any(s.pending for s in self.seen.values()):
            return "a transition is still under way"
        recover = self.phase in ("failed", "held", "pausing", "paused")
        self.phase, self.reason, self._hold_due = "starting", "", False
        self._resets = [n for n in RESET_ORDER if n in self.nodes] if recover else []
        self._reset_refused, self._relatched_n = (0, 0, ""), (0, 0)
        for seen in self.seen.values():
            seen.refused, seen.activated = 0, False
        return ""

    def latched(self) -> str:
        """The first latch an active node reports ("node: reason"), "" when none."""
        for name in self.nodes:
            seen = self.seen[name]
            if seen.latch and seen.state == ACTIVE:
                return f"{name}: {seen.latch}"
        return ""

    def shutdown(self) -> str:
        """Bring the cell down (deactivate in reverse order, then clean up); "" or why not."""
        if self.phase in ("stopping", "down", "finalizing", "finalized"):
            return f"already {self.phase}"
        self.phase, self._hold_due = "stopping", False
        return ""

    def pause(self) -> str:
        """Deactivate every node in reverse order (the planner stops, the simulator holds the
        tool); :meth:`startup` resumes; "" or why not now."""
        if self.phase not in ("starting", "active", "held", "failed"):
            return f"nothing to pause: the cell is {self.phase}"
        self.phase, self._hold_due, self._resets = "pausing", False, []
        return ""

    def finalize(self) -> str:
        """Bring the cell down and shut every node down (``finalized``: its process must be
        started again); "" or why not now."""
        if self.phase in ("finalizing", "finalized"):
            return f"already {self.phase}"
        self.phase, self._hold_due = "finalizing", False
        return ""

    # -- decisions -----------------------------------------------------------------
    def lost(self, steady_ns: int) -> list[tuple[str, float]]:
        """(node, silence [s]) of every node seen once whose heartbeat is older than
        ``heartbeat_timeout``; not a node in a transition the manager asked for (it runs in
        the node's executor, which beats no more meanwhile: a configure may settle the sheet
        or plan for seconds; ``transition_timeout`` bounds it)."""
        out = []
        for name in self.nodes:
            beat = self.seen[name].beat_ns
            if self.seen[name].pending:
                continue
            if beat is not None and (steady_ns - beat) / NS > self.heartbeat_timeout:
                out.append((name, (steady_ns - beat) / NS))
        return out

    def ready(self, steady_ns: int) -> bool:
        """Whether the monitor's newest /shaping/ready said ready, within ``ready_timeout``."""
        ready, at = self._ready
        return ready and at is not None and (steady_ns - at) / NS <= self.ready_timeout

    def waiting_for(self, steady_ns: int) -> str:
        """What a ``starting`` cell waits for ("" when nothing)."""
        if self.phase != "starting":
            return ""
        for name in self.nodes:
            seen = self.seen[name]
            if seen.state == "":
                return f"the {name}'s heartbeat (is it started, as a managed node?)"
            if seen.pending:
                return f"the {name}'s reply to {seen.pending}"
        if self._resets:
            refused, _, why = self._reset_refused
            return (f"the {self._resets[0]}'s reset (clearing the latches in order)"
                    + (f"; {why}, tried again every {RESET_RETRY_S:g} s" if refused else ""))
        monitor, planner = INTERLOCK
        others = all(self.seen[n].state == ACTIVE for n in self.nodes if n != planner)
        why = interlock_refusal(self.seen[monitor].state, self.ready(steady_ns))
        if others and why and self.seen[planner].state != ACTIVE:
            return f"the interlock before activating the {planner}: {why}"
        return ""

    def steps(self, steady_ns: int, previous_ns: int | None = None) -> list[Step]:
        """What to do now (each transition asked is marked pending until :meth:`answered`).

        ``previous_ns``: the manager itself stood still since its check at that time (a busy
        machine; :class:`~rheo_shaping.safety.watchdog.StallGuard`), so beats may wait unread:
        a node whose beat was fresh at that check is judged at the next one, not now."""
        self._steady_ns = steady_ns
        if self.phase in ("starting", "active", "held"):
            # (a lost node has a beat: lost() judges only nodes seen once)
            lost = [(n, age) for n, age in self.lost(steady_ns) if previous_ns is None
                    or (previous_ns - (self.seen[n].beat_ns or 0)) / NS
                    > self.heartbeat_timeout]
            left = [n for n in self.nodes if self._expects_active(n)
                    and self.seen[n].state not in (ACTIVE, "")]
            if lost:
                name, silence = lost[0]
                self._fail(f"{name} lost: no heartbeat for {silence:.2f} s "
                           f"(heartbeat_timeout {self.heartbeat_timeout:g} s)")
            elif left:
                self._fail(f"{left[0]} left the active state unasked (now "
                           f"{self.seen[left[0]].state})")
        if self.phase in ("active", "held"):
            latch = self.latched()
            self.phase, self.reason = ("held", f"holds: {latch}") if latch else ("active", "")
        if self.phase == "starting":
            steps = self._bring_up(steady_ns)
            if self.phase != "failed":
                return steps
        if self.phase == "failed":
            hold = [Step("hold", reason=self.reason)] if self._hold_due else []
            self._hold_due = False
            return hold + self._keep_safe(steady_ns)
        if self.phase in ("stopping", "pausing", "finalizing"):
            return self._bring_down()
        return []

    # -- internals -----------------------------------------------------------------
    def _expects_active(self, name: str) -> bool:
        """Whether ``name`` should be active now: the cell is up, or this bring-up has
        activated it (and no transition of it is under way)."""
        seen = self.seen[name]
        return not seen.pending and (self.phase == "active" or seen.activated)

    def _ask(self, name: str, transition: str) -> list[Step]:
        seen = self.seen[name]
        seen.pending, seen.asked_at = transition, seen.transitions
        seen.asked_ns, seen.resent, seen.refusal = self._steady_ns, 0, None
        return [Step(transition, name)]

    def unheard(self, steady_ns: int) -> list[tuple[str, str]]:
        """(node, transition) of every pending transition to send again: its node's beats of
        the last :data:`UNHEARD_S` (the process asked, its state and count unchanged) show
        the request never arrived."""
        out = []
        for name in self.nodes:
            seen = self.seen[name]
            instance, state, count = seen.heard
            if (seen.pending in TRANSITIONS and seen.refusal is None
                    and instance == seen.instance and state == seen.state
                    and count == seen.asked_at and seen.beat_ns is not None
                    and seen.beat_ns - seen.asked_ns >= UNHEARD_S * NS):
                seen.asked_ns, seen.resent = steady_ns, seen.resent + 1
                out.append((name, seen.pending))
        return out

    def _bring_up(self, steady_ns: int) -> list[Step]:
        if any(s.pending for s in self.seen.values()):
            return []
        if any(self.seen[n].state == "" for n in self.nodes):
            return []                                  # not every node is up yet
        for name in self.nodes:
            state = self.seen[name].state
            if state == FINALIZED:
                self._fail(f"the {name} is finalized: restart its process")
                return []
            if state == UNCONFIGURED:
                return self._ask(name, "configure")
        monitor, planner = INTERLOCK
        for name in self.nodes:
            if self.seen[name].state == ACTIVE:
                self.seen[name].activated = True
                continue
            if name == planner and self._resets:
                break                                  # the latches first (a recovery)
            if name == planner and interlock_refusal(self.seen[monitor].state,
                                                     self.ready(steady_ns)):
                return self._relatched(steady_ns)      # waits for the monitor (waiting_for)
            return self._ask(name, "activate")
        if self._resets:
            if steady_ns < self._reset_refused[1]:
                return []                              # tried again in a moment
            return self._ask(self._resets[0], "reset")
        self.phase = "active"
        return []

    def _relatched(self, steady_ns: int) -> list[Step]:
        """Before the planner is activated, a node that latched (again) is cleared again: on
        a busy machine a restarted monitor can abort on stale data while its simulator,
        still holding, does not wait for it.  At most :data:`RESET_RETRIES` times, one every
        :data:`RESET_RETRY_S`; then the cell fails naming the latch."""
        latched = [n for n in RESET_ORDER if n in self.nodes and n != INTERLOCK[1]
                   and self.seen[n].latch and self.seen[n].state == ACTIVE]
        count, due = self._relatched_n
        if not latched or steady_ns < due:
            return []
        name = latched[0]
        if count >= RESET_RETRIES:
            self._fail(f"the {name} latched again before the planner could start "
                       f"({RESET_RETRIES} resets): {self.seen[name].latch}")
            return []
        self._relatched_n = (count + 1, steady_ns + int(RESET_RETRY_S * NS))
        self._resets = [name]
        return self._ask(name, "reset")

    def _fail(self, reason: str) -> None:
        """The cell fails: the hold and the planner's deactivation follow (:meth:`steps`)."""
        if self.phase != "failed":
            self.phase, self.reason, self._hold_due = "failed", reason, True
        self._resets = []
        for seen in self.seen.values():
            seen.activated = False

    def _keep_safe(self, steady_ns: int) -> list[Step]:
        """The planner is deactivated while it is alive and active (a lost planner: nothing
        to ask, its stream has stopped and the tool holds)."""
        name = INTERLOCK[1]
        planner = self.seen.get(name)
        if planner is None or planner.pending or planner.state != ACTIVE:
            return []
        if any(n == name for n, _ in self.lost(steady_ns)):
            return []
        return self._ask(name, "deactivate")

    def _bring_down(self) -> list[Step]:
        """Deactivate in reverse order; then (not pausing) clean up; then (finalizing) shut
        down; one transition at a time."""
        if any(s.pending for s in self.seen.values()):
            return []
        for name in reversed(self.nodes):
            if self.seen[name].state == ACTIVE:
                return self._ask(name, "deactivate")
        if self.phase == "pausing":
            self.phase = "paused"
            return []
        for name in reversed(self.nodes):
            if self.seen[name].state == INACTIVE:
                return self._ask(name, "cleanup")
        if self.phase == "finalizing":
            for name in reversed(self.nodes):
                if self.seen[name].state == UNCONFIGURED:
                    return self._ask(name, "shutdown")
            self.phase = "finalized"
            return []
        self.phase = "down"
        return []
