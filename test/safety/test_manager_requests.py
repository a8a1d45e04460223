"""The lifecycle manager's requests and reports without ROS (rheo_shaping.safety.manager)."""
from __future__ import annotations

import json
from types import SimpleNamespace

from rheo_shaping.safety.manager import Answer, Requests, cell_status
from rheo_shaping.units import NS


class Reply:
    def __init__(self, result=None):
        self.result_value, self.is_done = result, result is not None

    def done(self) -> bool:
        return self.is_done

    def result(self):
        return self.result_value


def test_a_request_is_sent_once_its_service_is_seen_and_answered_by_its_reply():
    r = Requests(timeout=2.0)
    seen: set[str] = set()
    sent: list[tuple[str, str]] = []
    replies: dict[str, Reply] = {}

    def send(node, transition):
        sent.append((node, transition))
        replies[node] = Reply()
        return replies[node]

    def collect(now):
        return r.collect(now, lambda n, t: n in seen, send, lambda *a: None)

    r.ask("monitor", "configure", 0)
    assert collect(NS) == [] and sent == []                  # no service yet: waits
    seen.add("monitor")
    assert collect(NS + 1) == [] and sent == [("monitor", "configure")]
    assert collect(NS + 2) == [] and sent == [("monitor", "configure")]   # sent once
    replies["monitor"].result_value = SimpleNamespace(success=True, message="")
    replies["monitor"].is_done = True
    assert collect(NS + 3) == [Answer(node="monitor", transition="configure", ok=True,
                                      replied=True)]
    assert not r.waiting and not r.calls
    # a refusal carries the node's message, or says where to look
    r.ask("planner", "activate", 0)
    seen.add("planner")
    collect(1)
    replies["planner"].result_value = SimpleNamespace(success=False, message="")
    replies["planner"].is_done = True
    assert collect(2) == [Answer(node="planner", transition="activate", ok=False,
                                 why="the node refused it (its log says why)", replied=True)]


def test_requests_out_of_time_are_answered_as_failures_and_their_replies_dropped():
    r = Requests(timeout=2.0)
    dropped = []
    r.ask("simulator", "configure", 0)
    assert r.collect(2 * NS, lambda n, t: False, None, None) == []        # at the limit
    assert r.collect(2 * NS + 1, lambda n, t: False, None, None) == [Answer(
        node="simulator", transition="configure", ok=False,
        why="no simulator/change_state service within 2 s")]
    r.ask("monitor", "reset", 0)
    pending = Reply()
    r.collect(1, lambda n, t: True, lambda n, t: pending,
              lambda n, t, f: dropped.append((n, t, f)))
    out = r.collect(2 * NS + 1, lambda n, t: True, None,
                    lambda n, t, f: dropped.append((n, t, f)))
    assert out == [Answer(node="monitor", transition="reset", ok=False,
                          why="no reply within 2 s")]
    assert dropped == [("monitor", "reset", pending)]


def test_the_cells_status_and_its_diagnostic_level():
    states = {"simulator": "active", "monitor": "inactive", "planner": ""}
    text, level, message, values = cell_status("starting", "", "monitor: activate", states)
    assert json.loads(text) == {"phase": "starting", "reason": "", "waiting_for":
                                "monitor: activate", "nodes": states}
    assert (level, message) == ("WARN", "starting: waiting for monitor: activate")
    assert values == {"simulator": "active", "monitor": "inactive", "planner": "unseen"}
    assert cell_status("active", "", "", states)[1:3] == ("OK", "active")
    assert cell_status("failed", "monitor lost", "", states)[1:3] == (
        "ERROR", "failed: monitor lost")
    assert cell_status("held", "the simulator holds: abort", "", states)[1:3] == (
        "ERROR", "the simulator holds: abort")
    assert cell_status("idle", "", "", states)[1:3] == ("WARN", "idle")


def test_a_request_its_node_shows_no_sign_of_is_sent_again_or_its_clients_made_again():
    """Sent: the first call's reply is dropped and the request waits to be sent again, its
    time-out counted from the first ask.  Never sent (the node's service not seen while it
    beats): its clients are made again, at most every REMAKE_S."""
    from rheo_shaping.safety.manager import REMAKE_S
    r = Requests(timeout=120.0)
    dropped, sent = [], []
    r.ask("monitor", "configure", 0)
    r.collect(NS, lambda n, t: True, lambda n, t: sent.append((n, t)) or Reply(), None)
    assert r.unheard("monitor", 2 * NS, lambda *a: dropped.append(a[:2])) == "resend"
    assert dropped == [("monitor", "configure")] and r.waiting == {"monitor": ("configure", 0)}
    never = lambda *a: None                                  # noqa: E731
    assert r.unheard("monitor", 3 * NS, never) == "remake"   # now unsent: a new client
    assert r.unheard("monitor", 3 * NS + int(REMAKE_S * NS) - 1, never) == ""
    assert r.unheard("monitor", 3 * NS + int(REMAKE_S * NS), never) == "remake"
    assert r.unheard("planner", 9 * NS, never) == ""          # nothing asked of it
