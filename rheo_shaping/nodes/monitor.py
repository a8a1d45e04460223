"""The ``monitor`` node: aborts the shaping before the sheet tears, and on any doubt.

Inputs: ``/sheet/tensions`` and ``/sheet/contact_tension`` (the tensions),
``/sheet/profile`` and ``/tool/wrench`` (their header stamps are checked).
It aborts (``/shaping/abort``, std_msgs/String, reliable + transient local,
the reason in ``data``) when

* a tension reaches ``abort_ratio x material.F_break`` (``abort_ratio`` 0, the
  default: the largest ratio safety principle 4 allows at the cell's
  configured speed, from tension rates the core computes at start);
* the trend of the largest tension (least squares over ``trend_window``)
  predicts that threshold within ``detect_time + stop_time`` (the tool's
  reaction and jerk-limited stopping time);
* a tension is NaN or infinite (safety principle 2);
* a header stamp is zero or lies in the future (safety principle 2; on simulated time
  only if it is still ahead of the node's clock ``max_data_age`` later);
* the tension data go stale: no sample for ``max_data_age`` on the steady
  clock (a watchdog timer that does not depend on /clock, safety principle 1), a QoS
  deadline missed, or stamps older than ``max_stamp_age`` on the node clock;
  no data within ``startup_timeout`` of the start is a fault too.

The abort latches (safety principle 3) until ``~/reset`` (std_srvs/Trigger), which also
clears the transient-local abort (the publisher is re-created).  The monitor
publishes a heartbeat ``/shaping/ready`` (std_msgs/Bool) every ``period``:
true while it has fresh, valid data and has not aborted; the planner moves only
then (the interlock, safety principle 6).  ``/diagnostics``: OK / WARN / ERROR (STALE
while waiting for data) with tension, safety factor and data age.
"""
from __future__ import annotations

import math
import sys
from collections import deque

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from std_msgs.msg import Bool, Float64, Float64MultiArray, String
from std_srvs.srv import Trigger

from ..params.node_params import MonitorNodeParams
from ..params.params import CellParams
from ..safety.abort_budget import abort_horizon, configured_speed_threshold
from ..params.schema import ParameterError
from ..safety.watchdog import StallGuard
from . import messages as m
from . import topics as T
from .ros_params import SchemaParameters
from .spin import run_node

NS = 1_000_000_000
TENSION_TOPICS = (T.TENSIONS.contract, T.CONTACT_TENSION.contract)
STAMPED_TOPICS = (T.PROFILE.contract, T.TOOL_WRENCH.contract)


class MonitorNode(Node):
    """Watches the sheet's tensions; aborts, latches, reports."""

    def __init__(self, **node_kwargs):
        super().__init__('monitor', **node_kwargs)
        self.get_logger().info('starting')
        self.params = SchemaParameters(self, {"cell": CellParams, "settings": MonitorNodeParams},
                                       on_change=self._on_parameters,
                                       cli_args=node_kwargs.get('cli_args'))
        self._set_ratio()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        s = self.settings
        self.pub_abort = self._publisher(T.ABORT)
        self.pub_ready = self._publisher(T.READY)
        self.pub_diag = self._publisher(T.DIAGNOSTICS)
        self._subs = []
        self._subscribe(s.max_data_age)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self._clear()
        self._watchdog_guard = StallGuard(0.5 * s.max_data_age)
        self._watchdog = self.create_timer(s.period, self._on_watchdog, clock=self._steady)
        self._diag_timer = self.create_timer(s.diagnostics_period, self._publish_diagnostics,
                                             clock=self._steady)
        self.get_logger().info(
            f"monitor up: abort at {self.threshold:.4f} N = {self.ratio:.3f} x F_break "
            f"{self.cell.material.F_break:g} N; trend horizon {self.horizon:.3f} s; "
            f"data older than {s.max_data_age:g} s is a fault")

    # -- parameters -------------------------------------------------------------------
    @property
    def cell(self) -> CellParams:
        return self.params["cell"]

    @property
    def settings(self) -> MonitorNodeParams:
        return self.params["settings"]

    @property
    def threshold(self) -> float:
        """F_abort [N]."""
        return self.ratio * self.cell.material.F_break

    @property
    def horizon(self) -> float:
        """detect_time + stop_time [s]: how far ahead the trend must stay below the threshold."""
        return abort_horizon(self.cell, self.settings.detect_time, self.settings.stop_time)

    def _set_ratio(self) -> None:
        """``abort_ratio``, or with 0 the principle-4 bound at the configured speed (core runs)."""
        s = self.settings
        if s.abort_ratio > 0:
            self.ratio, self.budget = s.abort_ratio, None
            return
        cell = self.cell
        try:
            F_abort, r, rows = configured_speed_threshold(cell, self.horizon, s.noise_sigma)
        except (RuntimeError, ValueError) as exc:
            raise ParameterError(f"abort_ratio 0: the core could not compute the tension rates "
                                 f"({exc}); set abort_ratio") from None
        Fb = cell.material.F_break
        if F_abort <= 0:
            raise ParameterError(
                f"abort_ratio 0: no threshold meets safety principle 4 at movement.speed "
                f"{cell.movement.speed:g} m/s (r = {r:.3f} N/s, detect_time + stop_time = "
                f"{self.horizon:.3f} s): lower the speed or set abort_ratio")
        self.ratio = F_abort / Fb
        self.budget = {"r": r, "horizon": self.horizon, "sigma": s.noise_sigma,
                       "rows": [(row.movement, row.F_max, row.r) for row in rows]}
        self.get_logger().info(
            f"abort_ratio 0: safety principle 4 at {cell.movement.speed * 1e3:g} mm/s: r = {r:.3f} N/s "
            f"(movements 1-4, core), F_abort = {Fb:g} - {r:.3f} x {self.horizon:.3f} - "
            f"3 x {s.noise_sigma:g} = {F_abort:.4f} N, ratio {self.ratio:.3f}")

    def _on_parameters(self, names: set[str]) -> None:
        if "max_data_age" in names:
            self._watchdog_guard = StallGuard(0.5 * self.settings.max_data_age)
            for sub in self._subs:
                self.destroy_subscription(sub)
            self._subscribe(self.settings.max_data_age)
        if "period" in names:
            self._watchdog.cancel()
            self.destroy_timer(self._watchdog)
            self._watchdog = self.create_timer(self.settings.period, self._on_watchdog,
                                               clock=self._steady)
        if "diagnostics_period" in names:
            self._diag_timer.cancel()
            self.destroy_timer(self._diag_timer)
            self._diag_timer = self.create_timer(self.settings.diagnostics_period,
                                                 self._publish_diagnostics, clock=self._steady)
        relevant = {"abort_ratio", "detect_time", "stop_time", "noise_sigma",
                    *self.params.names("cell")}
        try:
            if names & relevant:
                self._set_ratio()
        except ParameterError as exc:
            self._abort(f"no abort threshold after the parameter change: {exc}")   # fail safe
            return
        self.get_logger().info(f"parameters {sorted(names)} changed: abort at {self.threshold:.4f} N, "
                               f"trend horizon {self.horizon:.3f} s")

    def _publisher(self, topic: T.Topic):
        return self.create_publisher(topic.type, topic.name, topic.qos)

    def _subscribe(self, max_age: float) -> None:
        qos = T.tension_qos(max_age)
        self._subs = [
            self.create_subscription(
                T.TENSIONS.type, T.TENSIONS.name, self._on_tensions, qos,
                event_callbacks=SubscriptionEventCallbacks(
                    deadline=lambda e: self._on_deadline(T.TENSIONS.contract, e))),
            self.create_subscription(
                T.CONTACT_TENSION.type, T.CONTACT_TENSION.name, self._on_contact, qos,
                event_callbacks=SubscriptionEventCallbacks(
                    deadline=lambda e: self._on_deadline(T.CONTACT_TENSION.contract, e))),
            self.create_subscription(
                T.PROFILE.type, T.PROFILE.name,
                lambda msg: self._on_stamped(T.PROFILE.contract, msg), T.PROFILE.qos),
            self.create_subscription(
                T.TOOL_WRENCH.type, T.TOOL_WRENCH.name,
                lambda msg: self._on_stamped(T.TOOL_WRENCH.contract, msg), T.TOOL_WRENCH.qos),
        ]

    # -- state ------------------------------------------------------------------------
    def _clear(self) -> None:
        self.state = "waiting"                 # waiting -> ready -> aborted
        self.abort_reason = ""
        self._start = self._steady.now().nanoseconds
        self._rx: dict[str, int | None] = {t: None for t in TENSION_TOPICS + STAMPED_TOPICS}
        self._stamp_age: dict[str, float] = {}
        self._stamp_fault = ""
        self._future: dict[str, tuple[int, int]] = {}   # topic -> (stamp, steady arrival) [ns]
        self.tension = math.nan                # latest largest link tension [N]
        self.link = 0
        self.contact = math.nan
        self.F_seen = 0.0                      # largest tension since (re)start [N]
        self.trend_rate = math.nan             # N/s
        self._trend: deque[tuple[float, float]] = deque()

    @property
    def ready(self) -> bool:
        return self.state == "ready"

    def _age(self, topic: str, now: int) -> float:
        rx = self._rx[topic]
        return math.inf if rx is None else (now - rx) / NS

    def _abort(self, reason: str) -> None:
        if self.state == "aborted":
            return
        self.state, self.abort_reason = "aborted", reason
        self.pub_abort.publish(String(data=reason))
        self.pub_ready.publish(Bool(data=False))
        self.get_logger().error(f"ABORT: {reason}")
        self._publish_diagnostics()

    def _on_reset(self, request, response):
        self.destroy_publisher(self.pub_abort)      # drops the transient-local abort sample
        self.pub_abort = self._publisher(T.ABORT)
        was = self.abort_reason
        self._clear()
        response.success = True
        response.message = "re-armed" + (f" (was aborted: {was})" if was else "")
        self.get_logger().info(f"reset: {response.message}")
        return response

    # -- data -------------------------------------------------------------------------
    def _on_tensions(self, msg: Float64MultiArray) -> None:
        self._rx[T.TENSIONS.contract] = self._steady.now().nanoseconds
        values = np.asarray(msg.data, dtype=float)
        if values.size == 0:
            self._abort("empty /sheet/tensions message")
            return
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            self._abort(f"non-finite tension ({values[i]}) in link {i + 1} on /sheet/tensions")
            return
        i = int(np.argmax(values))
        self.tension, self.link = float(values[i]), i + 1
        self.F_seen = max(self.F_seen, self.tension)
        self._check(self.tension, f"link {self.link}")
        self._check_trend(self.tension)

    def _on_contact(self, msg: Float64) -> None:
        self._rx[T.CONTACT_TENSION.contract] = self._steady.now().nanoseconds
        value = float(msg.data)
        if not math.isfinite(value):
            self._abort(f"non-finite contact tension ({value}) on /sheet/contact_tension")
            return
        self.contact = value
        self._check(value, "contact tension")

    def _check(self, value: float, where: str) -> None:
        if self.state != "aborted" and value >= self.threshold:
            s = self.settings
            self._abort(f"tension {value:.4f} N ({where}) reached the abort threshold "
                        f"{self.threshold:.4f} N = {self.ratio:.3f} x F_break "
                        f"{self.cell.material.F_break:g} N")

    def _check_trend(self, value: float) -> None:
        s = self.settings
        now = self.get_clock().now().nanoseconds / NS
        if now <= 0.0:
            return
        tr = self._trend
        if tr and now < tr[-1][0]:
            tr.clear()                                  # the clock went back: start again
        tr.append((now, value))
        while tr and tr[0][0] < now - s.trend_window:
            tr.popleft()
        if len(tr) < s.trend_min_samples:
            self.trend_rate = math.nan
            return
        t = np.array([p[0] for p in tr])
        f = np.array([p[1] for p in tr])
        span = t[-1] - t[0]
        if span < 0.5 * s.trend_window:
            self.trend_rate = math.nan
            return
        tc = t - t.mean()
        self.trend_rate = float(np.dot(tc, f - f.mean()) / np.dot(tc, tc))
        if (s.trend_abort and self.state != "aborted" and self.trend_rate > 0.0
                and value + self.trend_rate * self.horizon >= self.threshold):
            self._abort(f"tension trend {self.trend_rate:.4f} N/s from {value:.4f} N predicts the "
                        f"abort threshold {self.threshold:.4f} N within {self.horizon:.3f} s "
                        f"(detect_time + stop_time)")

    def _on_stamped(self, topic: str, msg) -> None:
        self._rx[topic] = self._steady.now().nanoseconds
        stamp = m.stamp_ns(msg.header.stamp)
        if stamp == 0:
            self._abort(f"zero header stamp on {topic}")
            return
        now = self.get_clock().now().nanoseconds
        if now <= 0:
            return                                        # no clock yet (use_sim_time, no /clock)
        age = (now - stamp) / NS
        self._stamp_age[topic] = age
        if -age > self.settings.stamp_tolerance:
            if self.get_clock().ros_time_is_active:
                # On simulated time the node's clock is the newest /clock message it has
                # *processed*; a busy process can handle a data message before the /clock
                # messages that arrived with it. The stamp is judged again on the watchdog
                # (steady clock): still ahead after max_data_age -> abort.
                self._future.setdefault(topic, (stamp, self._steady.now().nanoseconds))
            else:
                self._abort(self._future_reason(topic, -age))
        elif age > self.settings.max_stamp_age:
            self._stamp_fault = (f"header stamp on {topic} is {age:.3f} s old "
                                 f"(max_stamp_age {self.settings.max_stamp_age:g} s)")
            if self.state == "ready":
                self._abort(f"stale data: {self._stamp_fault}")
        else:
            self._stamp_fault = ""

    def _future_reason(self, topic: str, ahead: float) -> str:
        return (f"header stamp on {topic} lies {ahead:.3f} s in the future of the node "
                f"clock (stamp_tolerance {self.settings.stamp_tolerance:g} s)")

    def _check_future(self, steady_now: int) -> None:
        """Future stamps held back on simulated time: clear once the clock has caught up,
        abort if one is still ahead after ``max_data_age`` of wall time."""
        now = self.get_clock().now().nanoseconds
        for topic, (stamp, arrived) in list(self._future.items()):
            ahead = (stamp - now) / NS
            if ahead <= self.settings.stamp_tolerance:
                del self._future[topic]
            elif (steady_now - arrived) / NS > self.settings.max_data_age:
                del self._future[topic]
                self._abort(self._future_reason(topic, ahead) + f", {(steady_now - arrived) / NS:.3f} s "
                            f"after it arrived")

    def _on_deadline(self, topic: str, event) -> None:
        if self.state == "ready":
            self._abort(f"stale data: QoS deadline of {self.settings.max_data_age:g} s missed on {topic}")

    # -- watchdog (steady clock) ------------------------------------------------------
    def _on_watchdog(self) -> None:
        s = self.settings
        now = self._steady.now().nanoseconds
        if self._future and self.state != "aborted":
            self._check_future(now)
        ages = {t: self._age(t, now) for t in TENSION_TOPICS}
        stale = [t for t, a in ages.items() if a > s.max_data_age]
        # this process stood still for over max_data_age / 2 (a busy machine): samples may
        # wait unread behind this timer, so they are judged at the next tick, not now
        stalled = self._watchdog_guard.check(now)
        if self.state == "ready" and stale and not stalled:
            t = stale[0]
            self._abort(f"stale data: no {t} for "
                        + (f"{ages[t]:.3f} s" if math.isfinite(ages[t]) else "ever")
                        + f" (max_data_age {s.max_data_age:g} s)")
        elif self.state == "waiting":
            clock_ok = self.get_clock().now().nanoseconds > 0
            if not stale and not self._stamp_fault and not self._future and clock_ok:
                self.state = "ready"
                self.get_logger().info("ready: fresh tension data")
            elif (now - self._start) / NS > s.startup_timeout:
                why = ("no " + ", ".join(stale) if stale else self._stamp_fault or "no clock")
                self._abort(f"not ready within startup_timeout {s.startup_timeout:g} s: {why}")
        self.pub_ready.publish(Bool(data=self.ready))

    def _publish_diagnostics(self) -> None:
        s = self.settings
        now = self._steady.now().nanoseconds
        ages = {t: self._age(t, now) for t in TENSION_TOPICS}
        F = self.tension
        if self.state == "aborted":
            level, message = "ERROR", f"aborted: {self.abort_reason}"
        elif self.state == "waiting":
            level, message = "STALE", "waiting for fresh tension data"
        elif math.isfinite(F) and F >= s.warn_ratio * self.threshold:
            level, message = "WARN", f"tension {F:.4f} N near the abort threshold {self.threshold:.4f} N"
        else:
            level, message = "OK", "tension below the abort threshold"
        F_break = self.cell.material.F_break
        values = {
            "state": self.state, "tension_max": F, "tension_link": self.link,
            "contact_tension": self.contact, "F_break": F_break, "abort_threshold": self.threshold,
            "safety_factor": F_break / F if math.isfinite(F) and F > 0 else math.inf,
            "largest_tension_seen": self.F_seen, "trend_rate": self.trend_rate,
            "data_age_tensions": ages[T.TENSIONS.contract],
            "data_age_contact_tension": ages[T.CONTACT_TENSION.contract],
            "stamp_age": max(self._stamp_age.values(), default=math.nan),
            "abort_reason": self.abort_reason,
        }
        self.pub_diag.publish(m.diagnostics_msg(self.get_clock().now().nanoseconds,
                                                "rheo_shaping/monitor", level, message, values))


def main(args=None):
    return run_node(MonitorNode, 'monitor', args)


if __name__ == '__main__':
    sys.exit(main())
