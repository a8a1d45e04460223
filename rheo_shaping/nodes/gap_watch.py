"""The ``gap_watch`` node: the model beside the running cell (issue 29, docs/gapwatch.md).

Inputs (relative names, the cell's namespace): ``tool/pose``,
``sheet/measured_profile``, ``tool/wrench`` (the measured streams) and
``tool/planned_trajectory`` (its stamp is the process start; a later plan starts a
new run).  The decisions live in the core: :class:`rheo_shaping.gapwatch.watch.GapWatch`
(the model and its states) and :class:`rheo_shaping.gapwatch.session.WatchSession` (which
sample is fed or dropped, when a run starts and is diagnosed, the worker's watchdog, what
the reports say): this node converts messages, runs the worker thread and publishes.

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
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ..gapwatch.feed import DiagnosisJobs
from ..gapwatch.floor import ResidualFloor, ResidualFloorError
from ..gapwatch.session import WatchSession
from ..jsonable import json_safe
from ..params.config import ConfigError, load_cell
from ..params.gapwatch_params import GapWatchNodeParams
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
        self.session = WatchSession(self.model, self.floor, s)     # the decisions (core)
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._pool: ProcessPoolExecutor | None = None
        self.jobs: DiagnosisJobs | None = None
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

    # -- callbacks: plain values into the session's queue -----------------------------------
    def _put(self, kind: str, stamp: float, value) -> None:
        self.session.put(kind, stamp, value)
        self._wake.set()

    def _on_pose(self, msg) -> None:
        self._put("pose", m.stamp_ns(msg.header.stamp) / NS, m.pose_xz(msg))

    def _on_profile(self, msg) -> None:
        self._put("profile", m.stamp_ns(msg.header.stamp) / NS, m.profile_points(msg))

    def _on_wrench(self, msg) -> None:
        f = msg.wrench.force
        self._put("wrench", m.stamp_ns(msg.header.stamp) / NS, (float(f.x), float(f.z)))

    def _on_plan(self, msg) -> None:
        t = m.stamp_ns(msg.header.stamp) / NS
        if t > 0:
            self._put("start", t, None)

    # -- the worker thread: the session's drain, and the diagnoses it asks for ---------------
    def _work(self) -> None:
        session, log = self.session, self.get_logger()
        while not self._stopping.is_set():
            session.worker_beat = session.clock()
            self._wake.wait(0.1)
            self._wake.clear()
            try:
                for event in session.drain():
                    if event.startswith("OK"):    # one severity per call site (rclpy)
                        log.info(event)
                    else:
                        log.warning(event)
                why = session.due_diagnosis(self.jobs is not None and self.jobs.busy)
                if why:
                    self._diagnose(why)
            except Exception as exc:  # noqa: BLE001 - the watch reports, it never takes the
                # node down (a core defect shows on /diagnostics with its reason)
                log.error(session.failed(exc), throttle_duration_sec=5.0)

    def _diagnose(self, why: str) -> tuple[bool, str]:
        """Write the run so far and start its diagnosis in the worker process."""
        from ..records.bag import write_record
        rec, refusal = self.session.run_record(self.jobs is not None and self.jobs.busy)
        if rec is None:
            return False, refusal
        if self.jobs is None:
            from ..parallel import local_pool
            self._pool = local_pool(1)        # spawned: this process has DDS threads
            self.jobs = DiagnosisJobs(self._pool, self.settings.diagnosis_baseline)
        name = f"gapwatch-{time.strftime('%Y%m%d-%H%M%S')}-{self.session.diagnoses}"
        self.session.diagnoses += 1
        rec_dir = self.report_dir / name / "record"
        try:
            rec_dir.parent.mkdir(parents=True, exist_ok=True)
            write_record(rec, rec_dir, start_stamp=self.session.start_stamp)
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
        if self._stopping.is_set():               # the node is stopping: its worker was ended
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
        response.success, response.message = self._diagnose("~/diagnose")
        return response

    # -- the reports ------------------------------------------------------------------------
    def _publish(self) -> None:
        stuck = self.session.watchdog()
        if stuck:
            self.get_logger().error(stuck)
        report = self.session.report()
        now = self.get_clock().now().nanoseconds
        self.pub_gap.publish(String(data=json.dumps(json_safe(report.body))))
        name = m.status_name(self.get_namespace(), "gap_watch")
        self.pub_diag.publish(m.diagnostics_msg(
            now, name, report.level if report.level in m.LEVELS else "ERROR", report.message,
            report.values, m.hardware_id(self.get_namespace())))
        core = self.session.core
        if core is not None and core.model_nodes is not None:
            self.pub_markers.publish(m.gap_markers_msg(now, core.model_nodes,
                                                       self.session.frame,
                                                       self.model.sheet.thickness,
                                                       report.body["level"]))

    def _end_work(self) -> None:
        """End the model's worker thread and a diagnosis still running (node destroyed, or
        a managed gap watch cleaned up)."""
        if getattr(self, "_stopping", None) is None:
            return                                  # not built (a managed node unconfigured)
        self._stopping.set()
        self._wake.set()
        if self._pool is not None:             # a diagnosis still running ends with the node
            workers = list((getattr(self._pool, "_processes", None) or {}).values())
            self._pool.shutdown(wait=False, cancel_futures=True)
            for w in workers:
                if w.is_alive():
                    w.terminate()
            self._pool = None

    def destroy_node(self):
        self._end_work()
        return super().destroy_node()


def main(args=None):
    return run_node(GapWatchNode, 'gap_watch', args)


if __name__ == '__main__':
    sys.exit(main())
