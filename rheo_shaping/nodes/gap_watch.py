"""The ``gap_watch`` node: the model beside the running cell (issue 29, docs/gapwatch.md).

Inputs (relative names, the cell's namespace): ``tool/pose``,
``sheet/measured_profile``, ``tool/wrench`` (the measured streams) and
``tool/planned_trajectory`` (its stamp is the process start; a later plan starts a
new run).  The decisions live in the core, :class:`rheo_shaping.gapwatch.watch.GapWatch`:
this node converts messages, queues them, and publishes.

* The callbacks only queue plain values (at most ``queue_limit``; the oldest go first).
  A worker thread of this process feeds the queue to the core, which steps the model;
  a sample that waited longer than ``max_lag`` of wall time is dropped, and the drops
  are counted on ``/diagnostics`` and ``shaping/gap``.  The executor never waits for
  the model, so a stalled model stalls neither this node's reports nor the cell (the
  cell does not wait for this node at all).
* Every ``publish_period`` (steady clock): ``shaping/gap`` (std_msgs/String, JSON: state,
  residuals per observable, window, run and phase, noise, lag, drops),
  ``/diagnostics`` (status ``rheo_shaping/gap_watch``, hardware id of the cell's
  namespace), ``shaping/gap_markers`` (the model's profile and the newest judged frame).
* On the first sustained WARN of a run (``diagnose_on_warn``), again at the end of a run
  that warned (the whole run), and on ``~/diagnose`` (std_srvs/Trigger) at any time: the
  run so far is written as a record
  (rheo_shaping/records) under ``report_dir`` and diagnosed in a worker process
  (rheo_shaping.parallel's local pool, one process, spawned); the verdict, its parameters
  and the report's path go out on ``shaping/gap_diagnosis`` (JSON, latched).
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
import threading
import time
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ..gapwatch.feed import DiagnosisJobs
from ..gapwatch.floor import ResidualFloor, ResidualFloorError
from ..gapwatch.queue import SampleQueue
from ..gapwatch.watch import GapWatch
from ..jsonable import json_safe
from ..params.config import ConfigError, load_cell
from ..params.node_params import GapWatchNodeParams
from ..params.cell import CellParams
from ..params.schema import ParameterError
from ..units import NS
from . import messages as m
from . import topics as T
from .guards import Presence
from .ros_params import SchemaParameters
from .spin import Yielded, build_or_destroy, run_node


#: Reader history of the measured streams (messages): 2 s of a x10 cell's 50 Hz pose.
READER_DEPTH = 1000
#: Wall time [s] the worker may spend on one sample before the watchdog calls it stuck.
WORKER_STALL = 30.0
#: Samples fed to the core between two of its updates while the queue is long.
UPDATE_EVERY = 200


def replace_depth(qos, depth: int):
    """``qos`` with a history of ``depth`` (the depth is not part of QoS matching)."""
    from rclpy.qos import QoSProfile
    return QoSProfile(history=qos.history, depth=depth, reliability=qos.reliability,
                      durability=qos.durability)


class GapWatchNode(Node):
    """Thin: messages to the core's queue, the core's status to messages."""

    def __init__(self, **node_kwargs):
        super().__init__('gap_watch', **node_kwargs)
        build_or_destroy(self, self._build, node_kwargs)

    def _build(self, node_kwargs: dict) -> None:
        self.params = SchemaParameters(self, {"cell": CellParams,
                                              "settings": GapWatchNodeParams},
                                       cli_args=node_kwargs.get('cli_args'))
        s = self.settings
        try:
            self.model = load_cell(s.model_file) if s.model_file else self.params["cell"]
        except ConfigError as exc:
            raise ParameterError(f"parameter 'model_file' = {s.model_file!r}: {exc}") from None
        try:
            self.floor = ResidualFloor.load(s.floor_file or None)
        except ResidualFloorError as exc:
            raise ParameterError(f"parameter 'floor_file' = {s.floor_file!r}: {exc}") from None
        self.report_dir = Path(s.report_dir or os.path.join(tempfile.gettempdir(),
                                                            "rheo_shaping_gapwatch"))
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._queue = SampleQueue(s.queue_limit)
        self._worker_beat = time.monotonic()         # the worker's last sign of life [s]
        self._stalled = False                        # the watchdog found the worker stuck
        self._early: deque = deque(maxlen=s.queue_limit)   # samples before the start
        self._wake = threading.Event()
        self._stop = threading.Event()
        self.dropped = {"queue full": 0, "waited longer than max_lag": 0, "the model is stuck": 0}
        self.received: dict[str, int] = {}
        self.core: GapWatch | None = None
        self.start_stamp: float | None = None
        self.snapshot: dict = {"level": "STALE", "message": "waiting for the process start "
                               "(tool/planned_trajectory)", "residuals": {}}
        self.lag = {"last_s": 0.0, "max_s": 0.0}
        self.frame = None
        self._pool: ProcessPoolExecutor | None = None
        self.jobs: DiagnosisJobs | None = None
        self.verdicts = 0
        self._warned_run = False
        self._end_diagnosed = False
        for topic, callback in ((T.TOOL_POSE, self._on_pose),
                                (T.MEASURED_PROFILE, self._on_profile),
                                (T.TOOL_WRENCH, self._on_wrench)):
            # a deep reader history: a burst waits in DDS (which takes it on its own threads)
            # while this process is busy, instead of overwriting the keep-last 10 samples
            self.create_subscription(topic.type, topic.name, callback,
                                     replace_depth(topic.qos, READER_DEPTH))
        sub = self.create_subscription
        sub(T.PLANNED_TRAJECTORY.type, T.PLANNED_TRAJECTORY.name, self._on_plan,
            T.PLANNED_TRAJECTORY.qos)
        self.pub_gap = self.create_publisher(T.GAP.type, T.GAP.name, T.GAP.qos)
        self.pub_verdict = self.create_publisher(T.GAP_DIAGNOSIS.type, T.GAP_DIAGNOSIS.name,
                                                 T.GAP_DIAGNOSIS.qos)
        self.pub_markers = self.create_publisher(T.GAP_MARKERS.type, T.GAP_MARKERS.name,
                                                 T.GAP_MARKERS.qos)
        self.pub_diag = self.create_publisher(T.DIAGNOSTICS.type, T.DIAGNOSTICS.name,
                                              T.DIAGNOSTICS.qos)
        self.create_service(Trigger, '~/diagnose', self._on_diagnose)
        self._worker = threading.Thread(target=self._work, name="gap_watch model", daemon=True)
        self._worker.start()
        self.create_timer(s.publish_period, self._publish, clock=self._steady)
        self.get_logger().info(
            f"gap watch up: model {'of ' + s.model_file if s.model_file else 'of the cell'}, "
            f"floor {s.floor_file or 'shipped'} (window {s.window:g} s, sustain {s.sustain:g} s)")
        self.presence = Presence(self, self._yield)

    @property
    def settings(self) -> GapWatchNodeParams:
        return self.params["settings"]

    def _yield(self, reason: str) -> None:
        raise Yielded(reason)

    # -- callbacks: plain values into the queue ---------------------------------------------
    def _put(self, item: tuple) -> None:
        self.received[item[0]] = self.received.get(item[0], 0) + 1
        if self._stalled:
            self.dropped["the model is stuck"] += 1
            return
        if self._queue.put(item, time.monotonic()):
            self.dropped["queue full"] += 1
        self._wake.set()

    def _on_pose(self, msg) -> None:
        x, z = m.pose_xz(msg)
        self._put(("pose", m.stamp_ns(msg.header.stamp) / NS, (x, z)))

    def _on_profile(self, msg) -> None:
        self._put(("profile", m.stamp_ns(msg.header.stamp) / NS, m.profile_points(msg)))

    def _on_wrench(self, msg) -> None:
        f = msg.wrench.force
        self._put(("wrench", m.stamp_ns(msg.header.stamp) / NS, (float(f.x), float(f.z))))

    def _on_plan(self, msg) -> None:
        t = m.stamp_ns(msg.header.stamp) / NS
        if t > 0:
            self._put(("start", t, None))

    # -- the worker thread: the core --------------------------------------------------------
    def _work(self) -> None:
        while not self._stop.is_set():
            self._worker_beat = time.monotonic()
            self._wake.wait(0.1)
            self._wake.clear()
            try:
                self._drain()
                self._end_of_run()
            except Exception as exc:  # noqa: BLE001 - the watch reports, it never takes the
                # node down (a core defect shows on /diagnostics with its reason)
                self.snapshot = {"level": "ERROR", "message": f"gap watch failed: "
                                 f"{type(exc).__name__}: {exc}", "residuals": {}}
                self.get_logger().error(self.snapshot["message"], throttle_duration_sec=5.0)

    def _drain(self) -> None:
        s = self.settings
        fed = 0
        while (item := self._queue.pop()) is not None:
            kind, stamp, value, rx = item
            self._worker_beat = now = time.monotonic()
            wait = now - rx
            if kind == "start":
                if self.start_stamp is None or stamp > self.start_stamp + 1e-9:
                    self._new_run(stamp)
                continue
            if wait > s.max_lag:
                self.dropped["waited longer than max_lag"] += 1
                continue
            core = self.core
            if core is None:
                if s.wait_for_plan:           # kept until the process start is known
                    self._early.append((kind, stamp, value, rx))
                    continue
                core = self._new_run(stamp)
            if kind == "profile":
                if core.profile(stamp, value) is None:
                    self.frame = value
            elif kind == "pose":
                core.pose(stamp, *value)
            else:
                core.wrench(stamp, *value)
            self.lag["last_s"] = wait
            self.lag["max_s"] = max(self.lag["max_s"], wait)
            fed += 1
            if fed >= UPDATE_EVERY:           # keep the model moving through a long queue
                self._update()
                fed = 0
        if fed:
            self._update()

    def _new_run(self, stamp: float) -> GapWatch:
        core = self.core = GapWatch(self.model, self.floor, self.settings)
        core.start(stamp)
        # samples of this run that came before its start (the plan is latched and may
        # arrive after the first states): fed now; the rest is the cell at rest before it
        early = [e for e in self._early if e[1] >= stamp - 1e-9]
        self._early.clear()
        for kind, t, value, _ in early:
            if kind == "profile":
                core.profile(t, value)
            elif kind == "pose":
                core.pose(t, *value)
            else:
                core.wrench(t, *value)
        self.start_stamp = stamp
        self._warned_run = False
        self._end_diagnosed = False
        self.get_logger().info(f"process start at stamp {stamp:.3f} s: watching a new run")
        return core

    def _update(self) -> None:
        core = self.core
        assert core is not None                 # called once a run is watched (_drain)
        for event in core.update():
            self.get_logger().warning(event) if not event.startswith("OK") else \
                self.get_logger().info(event)
        st = core.status()
        self.snapshot = {"level": st.level, "message": st.message,
                         "residuals": st.residuals, "first_warn_s": st.first_warn,
                         "first_error_s": st.first_error, "cpu_s": core.cpu_s}
        if (st.level in ("WARN", "ERROR") and not self._warned_run
                and self.settings.diagnose_on_warn):
            self._warned_run = True
            self._diagnose(core, "sustained WARN")

    def _end_of_run(self) -> None:
        """A run that warned is diagnosed again, whole, once its process has ended (the
        diagnosis at WARN saw only its beginning); retried while one still runs."""
        core = self.core
        if (core is None or self._end_diagnosed or not self.settings.diagnose_on_warn
                or core.first_warn is None or not core.ended):
            return
        started, _ = self._diagnose(core, "the end of a run that warned")
        self._end_diagnosed = started or not (self.jobs is not None and self.jobs.busy)

    # -- the diagnosis ----------------------------------------------------------------------
    def _diagnose(self, core: GapWatch, why: str) -> tuple[bool, str]:
        """Write the run so far and start its diagnosis in the worker process."""
        from ..records.bag import write_record
        if self.jobs is None:
            from ..parallel import local_pool
            self._pool = local_pool(1)        # spawned: this process has DDS threads
            self.jobs = DiagnosisJobs(self._pool, self.settings.diagnosis_baseline)
        if self.jobs.busy:
            return False, "a diagnosis is running"
        rec = core.record()
        if rec.pose_t.size < 2 or len(rec.profiles) < 2:
            return False, "not enough of the run yet (two poses and two camera frames)"
        name = f"gapwatch-{time.strftime('%Y%m%d-%H%M%S')}-{self.verdicts}"
        self.verdicts += 1
        rec_dir = self.report_dir / name / "record"
        try:
            rec_dir.parent.mkdir(parents=True, exist_ok=True)
            write_record(rec, rec_dir, start_stamp=self.start_stamp)
        except (OSError, ValueError) as exc:
            return False, f"cannot write the record to {rec_dir}: {exc}"
        future = self.jobs.submit(str(rec_dir), str(self.report_dir / name / "report"))
        if future is None:
            return False, "a diagnosis is running"
        future.add_done_callback(self._on_verdict)
        self.get_logger().info(f"{why}: diagnosing {rec_dir} in a worker process")
        self.pub_verdict.publish(String(data=json.dumps(
            {"state": "running", "record": str(rec_dir), "why": why})))
        return True, f"diagnosing {rec_dir}"

    def _on_verdict(self, future) -> None:
        if self._stop.is_set():               # the node is stopping: its worker was ended
            return
        try:
            v = future.result()
        except Exception as exc:  # noqa: BLE001 - a worker that died is reported
            v = {"verdict": "failed", "error": f"{type(exc).__name__}: {exc}"}
        v["state"] = "done"
        try:
            self.pub_verdict.publish(String(data=json.dumps(json_safe(v))))
        except Exception:  # noqa: BLE001 - the node was destroyed meanwhile (the pool's thread)
            return
        self.get_logger().info(f"diagnosis: {v.get('verdict')} {v.get('parameters', '')} "
                               f"report {v.get('report', '')} {v.get('error', '')}")

    def _on_diagnose(self, request, response):
        core = self.core
        if core is None:
            response.success, response.message = False, "no run yet (no process start seen)"
            return response
        response.success, response.message = self._diagnose(core, "~/diagnose")
        return response

    # -- the reports ------------------------------------------------------------------------
    def _publish(self) -> None:
        self._watch_worker()
        snap = self.snapshot
        waiting, oldest = self._queue.waiting(time.monotonic())
        lag = {**self.lag, "queued": waiting, "oldest_queued_s": oldest}
        dropped = sum(self.dropped.values())
        level, message = snap["level"], snap["message"]
        if dropped and level in ("OK", "STALE"):
            level = "WARN"
        if dropped:
            message += f"; {dropped} samples dropped ({self._drop_text()})"
        if oldest > self.settings.max_lag:
            message += f"; the model lags {oldest:.1f} s behind the cell"
        refused = snap.get("residuals", {}).get("refused", {})
        if refused:
            message += f"; {sum(refused.values())} samples refused"
        body = {**snap, "lag": lag, "dropped": dict(self.dropped), "received": dict(self.received),
                "diagnoses": self.verdicts}
        now = self.get_clock().now().nanoseconds
        self.pub_gap.publish(String(data=json.dumps(json_safe(body))))
        r = snap.get("residuals") or {}
        values = {"state": snap["level"], "process time [s]": r.get("process_time_s", 0.0),
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
        name = m.status_name(self.get_namespace(), "gap_watch")
        self.pub_diag.publish(m.diagnostics_msg(now, name,
                                                level if level in m.LEVELS else "ERROR",
                                                message, values,
                                                m.hardware_id(self.get_namespace())))
        core = self.core
        if core is not None and core.model_nodes is not None:
            self.pub_markers.publish(m.gap_markers_msg(now, core.model_nodes, self.frame,
                                                       self.model.sheet.thickness,
                                                       snap["level"]))

    def _watch_worker(self) -> None:
        """The watchdog of the worker thread: stuck on one sample for over WORKER_STALL, it is
        reported (ERROR) and nothing more is queued for it, so memory stays bounded."""
        stuck = time.monotonic() - self._worker_beat
        if not self._stalled and stuck > WORKER_STALL:
            self._stalled = True
            self.dropped["the model is stuck"] += self._queue.clear()
            self.snapshot = {"level": "ERROR", "residuals": {},
                             "message": f"the model has been stuck on one sample for "
                                        f"{stuck:.0f} s: no more samples are queued"}
            self.get_logger().error(self.snapshot["message"])

    def _drop_text(self) -> str:
        return ", ".join(f"{k}: {v}" for k, v in self.dropped.items() if v)

    def destroy_node(self):
        self._stop.set()
        self._wake.set()
        if self._pool is not None:             # a diagnosis still running ends with the node
            workers = list((getattr(self._pool, "_processes", None) or {}).values())
            self._pool.shutdown(wait=False, cancel_futures=True)
            for w in workers:
                if w.is_alive():
                    w.terminate()
        return super().destroy_node()


def main(args=None):
    return run_node(GapWatchNode, 'gap_watch', args)


if __name__ == '__main__':
    sys.exit(main())
