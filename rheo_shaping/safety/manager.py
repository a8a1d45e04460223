"""The lifecycle manager's requests and reports without ROS: which transition requests are
waiting for their node's service, which await a reply, which ran out of time; and what the
manager says of the cell on its status topic and ``/diagnostics``.  Times are steady-clock
nanoseconds; a reply is any object with ``done()`` and ``result()`` (a future).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Callable, Protocol

from ..units import NS


#: Wall time [s] between two new clients of a node whose service stays unseen while it beats
#: (seen once in fresh-clone CI: a restarted monitor's configure unsent for 100 s).
REMAKE_S = 5.0


class Reply(Protocol):
    """A service call's future."""

    def done(self) -> bool: ...

    def result(self) -> Any: ...


@dataclass(frozen=True, kw_only=True)
class Answer:
    """What became of one request: the node, its transition, success, why not."""

    node: str
    transition: str
    ok: bool
    why: str = ""
    replied: bool = False          # the node answered (a sign of life); not a time-out


class Requests:
    """Transition requests to the cell's nodes, at most one per node, each answered within
    ``timeout`` [s] of being asked (the service may appear late: a request acts, so it is
    sent once, when the service is seen)."""

    def __init__(self, timeout: float):
        self.timeout = float(timeout)
        self.waiting: dict[str, tuple[str, int]] = {}            # node -> (transition, asked)
        self.calls: dict[str, tuple[str, Reply, int]] = {}        # node -> (..., reply, asked)
        self._remade: dict[str, int] = {}        # node -> when its clients were made again

    def ask(self, node: str, transition: str, now_ns: int) -> None:
        """Ask ``node`` for ``transition`` (sent by :meth:`collect` once its service is seen)."""
        self.waiting[node] = (transition, now_ns)

    def unheard(self, node: str, now_ns: int,
                drop: Callable[[str, str, Reply], None]) -> str:
        """``node``'s heartbeats show no sign of its request: what to do.  Sent: send it
        again ("resend"; ``drop`` forgets the first call's pending reply, the time-out still
        counts from the first ask).  Never sent, its service not seen while the node beats:
        make the node's clients again ("remake"), at most every :data:`REMAKE_S` (a new
        client needs its own discovery); else "" (wait)."""
        if node in self.calls:
            transition, reply, asked = self.calls.pop(node)
            drop(node, transition, reply)
            self.waiting[node] = (transition, asked)
            return "resend"
        if node in self.waiting and now_ns - self._remade.get(node, -REMAKE_S * NS) \
                >= REMAKE_S * NS:
            self._remade[node] = now_ns
            return "remake"
        return ""

    def collect(self, now_ns: int, ready: Callable[[str, str], bool],
                send: Callable[[str, str], Reply],
                drop: Callable[[str, str, Reply], None]) -> list[Answer]:
        """Send the waiting requests whose service is ``ready`` (``send`` makes the call),
        take the replies that came, and give up on those out of time (``drop`` forgets a
        call's pending reply); the answers, in that order."""
        limit = self.timeout * NS
        out: list[Answer] = []
        for node, (transition, asked) in list(self.waiting.items()):
            if ready(node, transition):
                del self.waiting[node]
                self.calls[node] = (transition, send(node, transition), asked)
            elif now_ns - asked > limit:
                del self.waiting[node]
                out.append(Answer(node=node, transition=transition, ok=False,
                                  why=f"no {node}/change_state service within "
                                      f"{self.timeout:g} s"))
        for node, (transition, reply, asked) in list(self.calls.items()):
            if reply.done():
                del self.calls[node]
                result = reply.result()
                ok = bool(result and result.success)
                why = getattr(result, "message", "") or "the node refused it (its log says why)"
                out.append(Answer(node=node, transition=transition, ok=ok,
                                  why="" if ok else why, replied=True))
            elif now_ns - asked > limit:
                del self.calls[node]
                drop(node, transition, reply)
                out.append(Answer(node=node, transition=transition, ok=False,
                                  why=f"no reply within {self.timeout:g} s"))
        return out


#: The diagnostic level of each phase of the cell (any other: WARN).
PHASE_LEVELS = {"failed": "ERROR", "active": "OK", "starting": "WARN", "held": "ERROR",
                "paused": "WARN", "down": "WARN", "finalized": "WARN"}


def cell_status(phase: str, reason: str, waiting: str,
                states: dict[str, str]) -> tuple[str, str, str, dict[str, str]]:
    """(the status topic's JSON, the diagnostic level, its message, its values) of a cell in
    ``phase`` (``reason``: why failed or held; ``waiting``: what it waits for;
    ``states``: each node's last lifecycle state, "" unseen)."""
    text = json.dumps({"phase": phase, "reason": reason, "waiting_for": waiting,
                       "nodes": states})
    message = {"failed": f"failed: {reason}", "held": reason,
               "starting": f"starting: waiting for {waiting}" if waiting else "starting"
               }.get(phase, phase)
    values = {n: s or "unseen" for n, s in states.items()}
    return text, PHASE_LEVELS.get(phase, "WARN"), message, values
