"""The gap watch node's decisions without ROS: which sample goes to the model and which is
dropped, when a run starts, when a run is diagnosed, whether the worker is stuck, and what
the reports say (the ``gap_watch`` node only converts messages and publishes).

:class:`WatchSession` is shared by two threads of the node: the executor's callbacks
:meth:`~WatchSession.put` samples and its timer reads :meth:`~WatchSession.report`; the
worker thread :meth:`~WatchSession.drain`\\ s the queue into the model.  The queue is under
one lock (:class:`~.queue.SampleQueue`); every other field is replaced whole or counted.
Times: stamps are the messages' [s]; waits are ``clock()`` seconds (monotonic).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable

from ..params.cell import CellParams
from ..params.gapwatch_params import GapWatchNodeParams
from ..records.record import Record
from .floor import ResidualFloor
from .queue import SampleQueue
from .watch import GapWatch

#: Wall time [s] the worker may spend on one sample before the watchdog calls it stuck.
WORKER_STALL = 30.0
#: Samples fed to the model between two of its updates while the queue is long.
UPDATE_EVERY = 200
#: The reasons a sample is dropped, in the reports' order.
DROPS = ("queue full", "waited longer than max_lag", "the model is stuck")
#: Why a run is diagnosed.
ON_WARN, AT_END = "sustained WARN", "the end of a run that warned"


@dataclass(frozen=True, kw_only=True)
class Report:
    """What the node publishes each period: the state, the message, the ``shaping/gap`` body
    and the ``/diagnostics`` values (units in their keys)."""

    level: str                       # OK, WARN, ERROR or STALE
    message: str
    body: dict[str, Any]
    values: dict[str, Any]


class WatchSession:
    """The gap watch's runs, one after another, and the samples that feed them."""

    def __init__(self, model: CellParams, floor: ResidualFloor, settings: GapWatchNodeParams,
                 clock: Callable[[], float] = time.monotonic):
        self.model, self.floor, self.settings, self.clock = model, floor, settings, clock
        self.queue = SampleQueue(settings.queue_limit)
        self.early: deque[tuple[Any, ...]] = deque(maxlen=settings.queue_limit)
        self.dropped = dict.fromkeys(DROPS, 0)
        self.received: dict[str, int] = {}
        self.core: GapWatch | None = None
        self.start_stamp: float | None = None     # the watched run's process start [s]
        self.snapshot: dict[str, Any] = {
            "level": "STALE", "message": "waiting for the process start "
            "(tool/planned_trajectory)", "residuals": {}}
        self.lag = {"last_s": 0.0, "max_s": 0.0}
        self.frame: Any = None                    # the newest frame the model judged
        self.worker_beat = clock()                # the worker's last sign of life [s]
        self.stalled = False                      # the watchdog found the worker stuck
        self.diagnoses = 0                        # diagnoses started
        self._warned_run = False                  # this run's WARN was diagnosed
        self._end_diagnosed = False               # this run's end was diagnosed

    # -- the executor's side ---------------------------------------------------------------
    def put(self, kind: str, stamp: float, value: Any) -> None:
        """A sample (``pose``, ``profile``, ``wrench``; ``start``: a plan's stamp > 0) to
        queue for the model; counted, dropped while the worker is stuck."""
        self.received[kind] = self.received.get(kind, 0) + 1
        if self.stalled:
            self.dropped["the model is stuck"] += 1
            return
        if self.queue.put((kind, stamp, value), self.clock()):
            self.dropped["queue full"] += 1

    # -- the worker's side -------------------------------------------------------------------
    def drain(self) -> list[str]:
        """Feed every queued sample to the model; the model's events (``OK ...`` or a
        warning) for the log.  A ``start`` later than the watched run's starts a new run;
        a sample older than ``max_lag`` is dropped; before a start (``wait_for_plan``)
        samples wait in ``early``."""
        s, events, fed = self.settings, [], 0
        while (item := self.queue.pop()) is not None:
            kind, stamp, value, rx = item
            self.worker_beat = now = self.clock()
            wait = now - rx
            if kind == "start":
                if self.start_stamp is None or stamp > self.start_stamp + 1e-9:
                    events.append(self.new_run(stamp))
                continue
            if wait > s.max_lag:
                self.dropped["waited longer than max_lag"] += 1
                continue
            core = self.core
            if core is None:
                if s.wait_for_plan:           # kept until the process start is known
                    self.early.append(item)
                    continue
                events.append(self.new_run(stamp))
                core = self.core
                assert core is not None
            if _feed(core, kind, stamp, value) and kind == "profile":
                self.frame = value
            self.lag["last_s"] = wait
            self.lag["max_s"] = max(self.lag["max_s"], wait)
            fed += 1
            if fed >= UPDATE_EVERY:           # keep the model moving through a long queue
                events += self._update()
                fed = 0
        if fed:
            events += self._update()
        return events

    def new_run(self, stamp: float) -> str:
        """Watch a new run from process start ``stamp`` [s]: the samples of it that came
        before its start are fed now; the rest is the cell at rest before it."""
        core = self.core = GapWatch(self.model, self.floor, self.settings)
        core.start(stamp)
        early = [e for e in self.early if e[1] >= stamp - 1e-9]
        self.early.clear()
        for kind, t, value, _ in early:
            _feed(core, kind, t, value)
        self.start_stamp = stamp
        self._warned_run = self._end_diagnosed = False
        return f"OK: process start at stamp {stamp:.3f} s: watching a new run"

    def _update(self) -> list[str]:
        core = self.core
        assert core is not None                 # called once a run is watched
        events = core.update()
        st = core.status()
        self.snapshot = {"level": st.level, "message": st.message,
                         "residuals": st.residuals, "first_warn_s": st.first_warn,
                         "first_error_s": st.first_error, "cpu_s": core.cpu_s}
        return events

    def failed(self, exc: BaseException) -> str:
        """The model raised: the watch says so (ERROR) and goes on; the message."""
        self.snapshot = {"level": "ERROR", "message": f"gap watch failed: "
                         f"{type(exc).__name__}: {exc}", "residuals": {}}
        return self.snapshot["message"]

    def due_diagnosis(self, busy: bool) -> str:
        """Why the run is to be diagnosed now ("" if not): its first sustained WARN
        (``diagnose_on_warn``), or the end of a run that warned (the whole run; asked again
        while a diagnosis runs)."""
        core = self.core
        if core is None or not self.settings.diagnose_on_warn:
            return ""
        if not self._warned_run and self.snapshot["level"] in ("WARN", "ERROR"):
            self._warned_run = True
            return ON_WARN
        if (not self._end_diagnosed and core.first_warn is not None and core.ended):
            self._end_diagnosed = not busy       # a running one: asked again later
            return AT_END if not busy else ""
        return ""

    def run_record(self, busy: bool) -> tuple[Record | None, str]:
        """The run so far as a record to diagnose, or None and why not."""
        if self.core is None:
            return None, "no run yet (no process start seen)"
        if busy:
            return None, "a diagnosis is running"
        rec = self.core.record()
        if rec.pose_t.size < 2 or len(rec.profiles) < 2:
            return None, "not enough of the run yet (two poses and two camera frames)"
        return rec, ""

    # -- the reports -----------------------------------------------------------------------
    def watchdog(self) -> str:
        """The worker stuck on one sample for over :data:`WORKER_STALL`: ERROR, the queue
        emptied and nothing more queued (memory stays bounded); the message, once."""
        stuck = self.clock() - self.worker_beat
        if self.stalled or stuck <= WORKER_STALL:
            return ""
        self.stalled = True
        self.dropped["the model is stuck"] += self.queue.clear()
        self.snapshot = {"level": "ERROR", "residuals": {},
                         "message": f"the model has been stuck on one sample for "
                                    f"{stuck:.0f} s: no more samples are queued"}
        return self.snapshot["message"]

    def report(self) -> Report:
        """The state, message, body and values of this period (a drop makes OK a WARN)."""
        snap = self.snapshot
        waiting, oldest = self.queue.waiting(self.clock())
        lag = {**self.lag, "queued": waiting, "oldest_queued_s": oldest}
        dropped = sum(self.dropped.values())
        level, message = snap["level"], snap["message"]
        if dropped and level in ("OK", "STALE"):
            level = "WARN"
        if dropped:
            message += f"; {dropped} samples dropped (" + ", ".join(
                f"{k}: {v}" for k, v in self.dropped.items() if v) + ")"
        if oldest > self.settings.max_lag:
            message += f"; the model lags {oldest:.1f} s behind the cell"
        refused = snap.get("residuals", {}).get("refused", {})
        if refused:
            message += f"; {sum(refused.values())} samples refused"
        body = {**snap, "lag": lag, "dropped": dict(self.dropped),
                "received": dict(self.received), "diagnoses": self.diagnoses}
        r = snap.get("residuals") or {}
        values: dict[str, Any] = {
            "state": snap["level"], "process time [s]": r.get("process_time_s", 0.0),
            "model time [s]": r.get("model_time_s", 0.0), "phase": r.get("phase", "")}
        for scope in ("window", "run"):
            for obs, unit, scale in (("profile_m", "mm", 1e3), ("force_N", "N", 1.0)):
                f = (r.get(scope) or {}).get(obs) or {}
                if f.get("rms") is not None:
                    values[f"{scope} {obs[:-2]} RMS [{unit}]"] = f["rms"] * scale
                    values[f"{scope} {obs[:-2]} systematic [{unit}]"] = f["systematic"] * scale
                    values[f"{scope} {obs[:-2]} [noise units]"] = f["z"]
        values.update({"lag [s]": lag["last_s"], "max lag [s]": lag["max_s"],
                       "queued": waiting, "dropped": dropped,
                       "refused": sum(refused.values()) if refused else 0})
        return Report(level=level, message=message, body=body, values=values)


def _feed(core: GapWatch, kind: str, stamp: float, value: Any) -> bool:
    """One sample to the model; True for a profile frame it judged."""
    if kind == "profile":
        return core.profile(stamp, value) is None
    if kind == "pose":
        core.pose(stamp, *value)
    else:
        core.wrench(stamp, *value)
    return False
