"""The managed cell's state-transition policy (rheo_shaping.safety.lifecycle), without ROS:
the bring-up order, the interlock as states, the safe state on a lost or fallen node."""
from __future__ import annotations

import pytest

from rheo_shaping.safety.lifecycle import CellLifecycle
from rheo_shaping.safety.lifecycle_terms import (ACTIVATE_RETRIES, CELL_ORDER, RESET_RETRIES,
                                                 Step, interlock_refusal)

S = 1_000_000_000          # ns per s


def beat_all(c: CellLifecycle, t: int, states: dict | None = None) -> None:
    for name in c.nodes:
        seen = c.seen[name]
        state = (states or {}).get(name, seen.state or "unconfigured")
        c.heartbeat(name, state, t, seen.transitions, "p-" + name)


def answer(c: CellLifecycle, steps: list[Step], success: bool = True) -> None:
    for step in steps:
        if step.action != "hold":
            c.answered(step.node, step.action, success)


def bring_up(c: CellLifecycle, t: int = 0) -> tuple[list[Step], int]:
    """Run the bring-up to the active cell; the transitions asked, in order."""
    asked = []
    c.startup()
    for _ in range(20):
        t += S // 10
        beat_all(c, t)
        c.monitor_ready(c.seen["monitor"].state == "active", t)
        steps = c.steps(t)
        asked += steps
        answer(c, steps)
        if c.phase == "active":
            return asked, t
    raise AssertionError(f"not active: {c.phase} {c.waiting_for(t)}")


def test_the_cell_is_configured_then_activated_in_order():
    c = CellLifecycle(heartbeat_timeout=1.0)
    asked, _ = bring_up(c)
    assert [(s.action, s.node) for s in asked] == [
        ("configure", "simulator"), ("configure", "monitor"), ("configure", "planner"),
        ("activate", "simulator"), ("activate", "monitor"), ("activate", "planner")]


def test_node_names_with_the_gap_watch_bring_it_up_before_the_planner_and_lose_the_cell_with_it():
    """node_names in any order: simulator, monitor, gap_watch, planner (the planner last,
    behind the interlock); a managed gap watch that goes silent fails the cell (a node the
    manager was given is one the cell needs)."""
    from rheo_shaping.params.manager_params import LifecycleManagerParams
    settings = LifecycleManagerParams(node_names=("planner", "gap_watch", "monitor",
                                                  "simulator"))
    c = CellLifecycle(heartbeat_timeout=1.0, nodes=settings.nodes)
    asked, t = bring_up(c)
    order = ["simulator", "monitor", "gap_watch", "planner"]
    assert [(s.action, s.node) for s in asked] == (
        [("configure", n) for n in order] + [("activate", n) for n in order])
    for _ in range(12):                                  # the gap watch silent for 1.2 s
        t += S // 10
        for name in ("simulator", "monitor", "planner"):
            seen = c.seen[name]
            c.heartbeat(name, seen.state, t, seen.transitions, "p-" + name)
        c.monitor_ready(True, t)
        steps = c.steps(t)
        answer(c, steps)
    assert c.phase == "failed" and c.reason.startswith("gap_watch lost: no heartbeat for ")


def test_node_names_must_name_every_node_of_a_cell():
    from rheo_shaping.params.manager_params import LifecycleManagerParams
    with pytest.raises(ValueError, match="missing monitor"):
        LifecycleManagerParams(node_names=("simulator", "planner", "gap_watch"))
    assert LifecycleManagerParams().nodes == CELL_ORDER


def test_nothing_is_asked_before_every_node_has_a_heartbeat():
    c = CellLifecycle(heartbeat_timeout=1.0)
    c.startup()
    c.heartbeat("simulator", "unconfigured", 0, 0, "a")
    assert c.steps(0) == []
    assert "monitor's heartbeat" in c.waiting_for(0)


def test_one_transition_at_a_time():
    c = CellLifecycle(heartbeat_timeout=1.0)
    c.startup()
    beat_all(c, 0)
    first = c.steps(0)
    assert first == [Step("configure", "simulator")]
    assert c.steps(0) == []                         # its reply is awaited
    assert "simulator's reply to configure" in c.waiting_for(0)


@pytest.mark.parametrize("state, ready, why", [
    ("inactive", True, "the monitor is inactive, not active"),
    ("", False, "the monitor is not seen yet, not active"),
    ("active", False, "active but not ready"),
    ("active", True, "")])
def test_interlock_as_states(state, ready, why):
    got = interlock_refusal(state, ready)
    assert (why in got) if why else got == ""


def test_the_planner_waits_until_the_monitor_is_active_and_ready():
    c = CellLifecycle(heartbeat_timeout=1.0)
    c.startup()
    t = 0
    for _ in range(10):                  # configure all, activate simulator and monitor
        t += S // 10
        beat_all(c, t)
        answer(c, c.steps(t))
    assert c.seen["monitor"].state == "active" and c.seen["planner"].state == "inactive"
    c.monitor_ready(False, t)
    assert c.steps(t) == []
    assert "interlock before activating the planner" in c.waiting_for(t)
    c.monitor_ready(True, t)
    assert c.steps(t) == [Step("activate", "planner")]


def test_an_old_ready_beat_does_not_open_the_interlock():
    c = CellLifecycle(heartbeat_timeout=1.0, ready_timeout=1.0)
    c.monitor_ready(True, 0)
    assert c.ready(S) and not c.ready(S + 1)


def test_a_refused_planner_activation_is_tried_again_then_fails_the_cell():
    c = CellLifecycle(heartbeat_timeout=1.0)
    c.startup()
    t = 0
    for _ in range(5):
        t += S // 10
        beat_all(c, t)
        answer(c, c.steps(t))
    c.monitor_ready(True, t)
    for attempt in range(ACTIVATE_RETRIES):
        steps = c.steps(t)
        assert steps == [Step("activate", "planner")], attempt
        answer(c, steps, success=False)
    assert c.phase == "failed" and "activate of the planner failed" in c.reason
    assert c.steps(t) == [Step("hold", reason=c.reason)]


def test_a_silent_monitor_fails_the_cell_the_tool_holds_and_the_planner_deactivates():
    c = CellLifecycle(heartbeat_timeout=0.5)
    _, t = bring_up(c)
    last = t
    t += S // 10
    for name in ("simulator", "planner"):           # the monitor's beats stop
        c.heartbeat(name, "active", t, c.seen[name].transitions, "p-" + name)
    assert c.steps(t) == []                         # within the timeout: nothing
    t = last + int(0.51 * S)
    for name in ("simulator", "planner"):
        c.heartbeat(name, "active", t, c.seen[name].transitions, "p-" + name)
    steps = c.steps(t)
    assert c.phase == "failed"
    assert c.reason.startswith("monitor lost: no heartbeat for 0.51 s")
    assert steps == [Step("hold", reason=c.reason), Step("deactivate", "planner")]
    answer(c, steps)
    assert c.steps(t) == []                         # latched, nothing more to do
    assert c.seen["planner"].state == "inactive"


def test_a_lost_planner_is_not_asked_anything_but_the_tool_holds():
    c = CellLifecycle(heartbeat_timeout=0.5)
    _, t = bring_up(c)
    t += S
    for name in ("simulator", "monitor"):
        c.heartbeat(name, "active", t, c.seen[name].transitions, "p-" + name)
    steps = c.steps(t)
    assert steps == [Step("hold", reason=c.reason)] and c.reason.startswith("planner lost")


def test_a_node_that_leaves_active_unasked_fails_the_cell():
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    t += S // 10
    beat_all(c, t, {"monitor": "inactive"})
    steps = c.steps(t)
    assert c.reason == "monitor left the active state unasked (now inactive)"
    assert steps == [Step("hold", reason=c.reason), Step("deactivate", "planner")]


def test_a_beat_sent_before_a_transition_reply_is_old_news():
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    # the planner's beat from before its activation (one transition fewer) arrives late
    c.heartbeat("planner", "inactive", t, c.seen["planner"].transitions - 1, "p-planner")
    assert c.steps(t) == [] and c.phase == "active"
    # a restarted planner (another process) is news whatever it counts
    c.heartbeat("planner", "unconfigured", t, 0, "p-planner-2")
    c.steps(t)
    assert c.phase == "failed" and "(now unconfigured)" in c.reason


def test_bring_down_deactivates_in_reverse_then_cleans_up():
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    assert c.shutdown() == ""
    asked = []
    for _ in range(10):
        t += S // 10
        beat_all(c, t)
        steps = c.steps(t)
        asked += steps
        answer(c, steps)
    assert [(s.action, s.node) for s in asked] == [
        ("deactivate", "planner"), ("deactivate", "monitor"), ("deactivate", "simulator"),
        ("cleanup", "planner"), ("cleanup", "monitor"), ("cleanup", "simulator")]
    assert c.phase == "down"


def _run(c: CellLifecycle, t: int, n: int = 12, latches: dict | None = None) -> list:
    """n checks of 0.1 s, every node beating (with ``latches``), each step answered."""
    asked = []
    for _ in range(n):
        t += S // 10
        for name in c.nodes:
            seen = c.seen[name]
            c.heartbeat(name, seen.state, t, seen.transitions, "p-" + name,
                        (latches or {}).get(name, ""))
        c.monitor_ready(c.seen["monitor"].state == "active", t)
        steps = c.steps(t)
        asked += steps
        answer(c, steps)
        for step in steps:                    # a reset clears the node's latch
            if step.action == "reset" and latches:
                latches.pop(step.node, None)
    return [(s.action, s.node) for s in asked]


def test_nav2_commands_pause_resume_reset_and_shutdown():
    """Nav2's manage_nodes commands: pause deactivates in reverse order (the tool holds: the
    simulator's latch), resume brings the cell back through the latches in order, reset
    deactivates and cleans up, shutdown also shuts every node down (finalized: nothing
    brings it back but new processes)."""
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    assert c.command("pause") == "" and c.phase == "pausing"
    assert _run(c, t) == [("deactivate", "planner"), ("deactivate", "monitor"),
                          ("deactivate", "simulator")]
    assert c.phase == "paused" and c.command("pause") == "nothing to pause: the cell is paused"
    assert c.command("resume") == ""
    asked = _run(c, t, latches={"simulator": "deactivated (lifecycle): the tool holds"})
    assert asked == [("activate", "simulator"), ("activate", "monitor"), ("reset", "monitor"),
                     ("reset", "simulator"), ("reset", "planner"), ("activate", "planner")]
    assert c.phase == "active"
    assert c.command("reset") == "" and _run(c, t)[-1] == ("cleanup", "simulator")
    assert c.phase == "down"
    assert c.command("shutdown") == ""
    assert _run(c, t) == [("shutdown", n) for n in ("planner", "monitor", "simulator")]
    assert c.phase == "finalized"
    assert c.command("startup") == "the cell is finalized: start its processes again"
    assert "unknown command 'restart'" in c.command("restart")


def _lost_configure(c: CellLifecycle) -> int:
    """The monitor's configure asked at t = 0 and never heard of: its process beats on,
    unconfigured, no transition counted; the time [ns] it is sent again."""
    c.startup()
    beat_all(c, 0)
    c.seen["simulator"].state = c.seen["planner"].state = "inactive"   # (configured before)
    assert c.steps(0) == [Step("configure", "monitor")]
    t = 0
    while not c.unheard(t):
        t += S // 10
        assert t <= S, "not sent again within UNHEARD_S of unchanged beats"
        c.heartbeat("monitor", "unconfigured", t, 0, "p-monitor")
    assert t == S                                 # 1.0 s of beats after the ask
    assert c.unheard(t) == []                     # once; the next only after another 1.0 s
    return t


def test_a_transition_request_lost_before_the_service_matched_is_sent_again():
    """A restarted node's service can match the manager's client after its heartbeat did:
    the request is lost (seen in test_lifecycle.py's recovery on a loaded machine: the
    manager waited out its 120 s transition_timeout).  The beats tell: the same process,
    unconfigured, no transition counted for 1.0 s after the ask."""
    c = CellLifecycle(heartbeat_timeout=5.0)
    t = _lost_configure(c)
    c.answered("monitor", "configure", True, steady_ns=t + S // 10)    # the second arrived
    assert c.seen["monitor"].state == "inactive" and not c.seen["monitor"].pending


def test_a_refused_duplicate_is_judged_by_the_next_heartbeat():
    """Sent again, a request may be a duplicate of one the node carried out (its reply lost):
    lifecycle refuses the duplicate.  The refusal waits for the node's next beat: done
    (a transition counted) is success; unchanged is the refusal."""
    c = CellLifecycle(heartbeat_timeout=5.0)
    t = _lost_configure(c)
    c.answered("monitor", "configure", False, "invalid transition", steady_ns=t + 1)
    assert c.seen["monitor"].pending == "configure" and c.phase == "starting"
    c.heartbeat("monitor", "inactive", t + 2, 1, "p-monitor")          # it had configured
    assert c.seen["monitor"].state == "inactive" and c.phase == "starting"
    c = CellLifecycle(heartbeat_timeout=5.0)
    t = _lost_configure(c)
    c.answered("monitor", "configure", False, "bad parameter", steady_ns=t + 1)
    c.heartbeat("monitor", "unconfigured", t + 2, 0, "p-monitor")       # it refused
    assert c.phase == "failed" and c.reason == "configure of the monitor failed: bad parameter"


def test_a_monitor_that_latches_before_the_planner_is_activated_is_cleared_again():
    """A restarted monitor on a busy machine can abort (stale data) while its simulator,
    still holding, does not wait for it: before the planner is activated, the latch is
    cleared again (its ~/reset, once a second), and the planner follows the interlock; a
    latch that keeps coming back fails the cell after RESET_RETRIES, naming it."""
    c = CellLifecycle(heartbeat_timeout=5.0)
    c.startup()
    t, asked = 0, []
    latch = {"monitor": "stale data: no /sheet/tensions for 0.800 s"}
    for _ in range(30):
        t += S // 10
        for name in c.nodes:
            seen = c.seen[name]
            c.heartbeat(name, seen.state or "unconfigured", t, seen.transitions, "p-" + name,
                        latch.get(name, ""))
        c.monitor_ready(c.seen["monitor"].state == "active" and not latch, t)
        steps = c.steps(t)
        asked += [(s.action, s.node) for s in steps]
        answer(c, steps)
        if ("reset", "monitor") in asked:
            latch = {}                                  # the reset cleared it
    assert asked[-2:] == [("reset", "monitor"), ("activate", "planner")], asked
    assert c.phase == "active"
    c = CellLifecycle(heartbeat_timeout=5.0)
    c.startup()
    t = 0
    for _ in range(10 * (RESET_RETRIES + 3)):          # a latch that always comes back
        t += S // 10
        for name in c.nodes:
            seen = c.seen[name]
            c.heartbeat(name, seen.state or "unconfigured", t, seen.transitions, "p-" + name,
                        "nan tension" if name == "monitor" else "")
        answer(c, c.steps(t))
    assert c.phase == "failed"
    assert c.reason == (f"the monitor latched again before the planner could start "
                        f"({RESET_RETRIES} resets): nan tension")


def test_startup_after_a_failure_clears_the_reason():
    c = CellLifecycle(heartbeat_timeout=0.5)
    _, t = bring_up(c)
    beat_all(c, t, {"simulator": "inactive"})
    answer(c, c.steps(t))
    assert c.phase == "failed"
    assert c.startup() == "" and c.reason == "" and c.phase == "starting"
    assert c.steps(t) == [Step("activate", "simulator")]


def test_a_heartbeat_timeout_not_above_the_beat_period_is_refused():
    with pytest.raises(ValueError, match="heartbeat_timeout 0.1 s"):
        CellLifecycle(heartbeat_timeout=0.1)


def test_a_lost_reply_is_answered_by_the_next_heartbeat():
    c = CellLifecycle(heartbeat_timeout=1.0)
    c.startup()
    beat_all(c, 0)
    assert c.steps(0) == [Step("configure", "simulator")]
    c.heartbeat("simulator", "inactive", 1, 1, "p-simulator")    # done; reply never comes
    assert c.seen["simulator"].pending == "" and c.seen["simulator"].state == "inactive"
    c.answered("simulator", "configure", True)                    # a late reply: no effect
    assert c.steps(2) == [Step("configure", "monitor")]


def test_a_stall_of_the_manager_itself_defers_the_verdict_by_one_check():
    c = CellLifecycle(heartbeat_timeout=0.5)
    _, t = bring_up(c)
    late = t + 2 * S                      # the manager stood still 2 s; beats wait unread
    assert c.steps(late, previous_ns=t) == [] and c.phase == "active"
    steps = c.steps(late + S // 20, previous_ns=late)    # still none: now they are lost
    assert c.phase == "failed" and steps[0].action == "hold"


def test_docs_lifecycle_manager_parameter_table_is_current():
    from pathlib import Path
    from rheo_shaping.params.manager_params import LifecycleManagerParams
    from rheo_shaping.params.node_params import parameter_table
    doc = (Path(__file__).resolve().parents[2] / "docs" / "ros.md").read_text()
    assert parameter_table(LifecycleManagerParams) in doc, \
        "docs/ros.md: regenerate the `lifecycle_manager` table"


def test_a_node_in_a_long_transition_is_not_lost_and_its_reply_is_a_sign_of_life():
    c = CellLifecycle(heartbeat_timeout=1.0)
    c.startup()
    beat_all(c, 0)
    assert c.steps(0) == [Step("configure", "simulator")]
    # the simulator settles its sheet for 5 s: no beat from it meanwhile
    for name in ("monitor", "planner"):
        c.heartbeat(name, "unconfigured", 5 * S, 0, "p-" + name)
    assert c.steps(5 * S) == [] and c.phase == "starting"
    c.answered("simulator", "configure", True, steady_ns=5 * S)
    assert c.steps(5 * S + S // 10) == [Step("configure", "monitor")]
    assert c.phase == "starting"


def _beat(c: CellLifecycle, t: int, latches: dict[str, str] | None = None,
          instances: dict[str, str] | None = None) -> None:
    for name in CELL_ORDER:
        seen = c.seen[name]
        c.heartbeat(name, seen.state, t, seen.transitions,
                    (instances or {}).get(name, seen.instance or "p-" + name),
                    (latches or {}).get(name, ""))


def test_a_latch_in_an_active_node_takes_the_cell_to_held_and_back():
    """The manager's `active` means the tool can move: a simulator that holds its tool (a
    rogue's acknowledgements, a tool limit) makes the cell `held`, named; it is active again
    once the latch has cleared."""
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    _beat(c, t + 1, {"simulator": "monitor lost: no /shaping/checked for over 0.5 s"})
    assert c.steps(t + 1) == []                     # the node's own latch stops the tool
    assert (c.phase, c.reason) == ("held", "holds: simulator: monitor lost: no "
                                           "/shaping/checked for over 0.5 s")
    _beat(c, t + 2)
    c.steps(t + 2)
    assert (c.phase, c.reason) == ("active", "")


def test_a_latch_of_an_inactive_node_does_not_hold_the_cell():
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    c.seen["planner"].state = "inactive"
    c.seen["planner"].activated = False
    c.phase = "held"
    _beat(c, t + 1, {"planner": "planner: deactivated (lifecycle)"})
    assert c.latched() == ""


def test_startup_after_a_failure_recovers_a_restarted_node_and_clears_the_latches_in_order():
    """The monitor killed and restarted: one startup configures and activates the newcomer,
    resets monitor, simulator and planner in that order (the simulator refuses to release its
    hold while its monitor is lost), then activates the planner behind the interlock."""
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    t += 2 * S                                      # the monitor dies: its beats stop
    for name in ("simulator", "planner"):
        seen = c.seen[name]
        c.heartbeat(name, seen.state, t, seen.transitions, seen.instance,
                    "abort: lifecycle_manager: monitor lost")
    steps = c.steps(t)
    assert c.phase == "failed" and c.reason.startswith("monitor lost: no heartbeat")
    assert steps == [Step("hold", reason=c.reason), Step("deactivate", "planner")]
    answer(c, steps)
    # the restarted monitor: another process, unconfigured
    c.heartbeat("monitor", "unconfigured", t, 0, "p-monitor-2")
    assert c.startup() == ""
    asked = []
    for _ in range(30):
        t += S // 10
        _beat(c, t, {n: c.seen[n].latch for n in CELL_ORDER},
              {"monitor": "p-monitor-2"})
        c.monitor_ready(c.seen["monitor"].state == "active", t)
        steps = c.steps(t)
        asked += [(s.action, s.node) for s in steps]
        answer(c, steps)
        if c.phase == "active":
            break
    assert asked == [("configure", "monitor"), ("activate", "monitor"), ("reset", "monitor"),
                     ("reset", "simulator"), ("reset", "planner"), ("activate", "planner")]
    assert c.phase == "active" and c.latched() == ""


def test_a_refused_reset_fails_the_recovery_with_the_nodes_reason():
    c = CellLifecycle(heartbeat_timeout=1.0)
    _, t = bring_up(c)
    _beat(c, t + 1, {"simulator": "a second writer of /shaping/checked: /rogue"})
    c.steps(t + 1)
    assert c.phase == "held" and c.startup() == ""
    steps = c.steps(t + 2)
    assert [(s.action, s.node) for s in steps] == [("reset", "monitor")]
    answer(c, steps)
    steps = c.steps(t + 3)
    assert [(s.action, s.node) for s in steps] == [("reset", "simulator")]
    # refused: tried again every second (a killed monitor's writer stays in the graph for
    # its DDS lease), RESET_RETRIES times, then the cell fails with the node's reason
    t = t + 3
    for k in range(1, RESET_RETRIES):
        c.answered("simulator", "reset", False, "not reset: a second writer of /shaping/checked",
                   steady_ns=t)
        assert c.phase == "starting" and "tried again every 1 s" in c.waiting_for(t)
        _beat(c, t + S - 1, {"simulator": "a second writer of /shaping/checked: /rogue"})
        assert c.steps(t + S - 1) == []
        t += S
        _beat(c, t, {"simulator": "a second writer of /shaping/checked: /rogue"})
        assert [(s.action, s.node) for s in c.steps(t)] == [("reset", "simulator")]
    c.answered("simulator", "reset", False, "not reset: a second writer of /shaping/checked",
               steady_ns=t)
    assert c.phase == "failed"
    assert c.reason == (f"the simulator refused its reset: not reset: a second writer of "
                        f"/shaping/checked ({RESET_RETRIES} times)")
