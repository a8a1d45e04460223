"""The monitor's decisions without ROS: when the shaping must stop (docs/safety.md).

:class:`TensionMonitor` is the safety state machine of the ``monitor`` node
(:mod:`rheo_shaping.nodes.monitor` only feeds it messages and clock readings and
publishes what it decides):

* states ``waiting`` -> ``ready`` -> ``aborted``; ``aborted`` latches until
  :meth:`TensionMonitor.reset` (safety principle 3);
* abort when a tension reaches the threshold ``ratio x F_break``, or (``trend_abort``)
  when the linear trend of the largest tension predicts it within ``horizon``;
* a non-finite tension, a zero or future header stamp, stale data (no sample for
  ``max_data_age`` on the steady clock, a missed deadline, stamps older than
  ``max_stamp_age``), no data within ``startup_timeout``: abort (principles 1, 2);
* in a lockstep cell (:attr:`TensionMonitor.cell_clock`: the simulator steps only on this
  monitor's acknowledgements) the stream that paces it (the link tensions) is stale when
  the cell's clock has run ``max_data_age`` past its newest sample at two watchdog ticks
  running (lost /clock messages date a sample early until the next one comes); the wall's
  age and the QoS deadline count there only beyond :data:`LOCKSTEP_WALL_FACTOR` x
  ``max_data_age`` (a starved machine slows such a cell; a clock that stands still that
  long has lost its simulator).  The contact tension, not acknowledged, is judged on the
  wall only, by the same bound (one of the link tensions, its samples may come later).

Times are integer nanoseconds: ``steady`` on a steady clock, ``clock`` on the node's
clock (simulated time when ``sim_time``; 0 while there is no clock yet).
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

from ..params.node_params import MonitorNodeParams
from ..sheet.metrics import safety_factor
from ..units import NS
from .trend import TensionTrend


def stale_on_cell_clock(settings: MonitorNodeParams, sim_time: bool) -> bool:
    """Judge staleness on the cell's clock: on simulated time, with ``stale_clock`` 'cell'
    (simulator and monitor on one executor) or 'auto' and acknowledging (the simulator then
    steps only on this monitor's acknowledgements)."""
    if not sim_time or settings.stale_clock == "wall":
        return False
    return settings.stale_clock == "cell" or settings.acknowledge


#: In a lockstep cell, the wall time [in max_data_age] after which a stream is stale though
#: the cell's clock stood still: the simulator (the clock) is lost.
LOCKSTEP_WALL_FACTOR = 10.0


class TensionMonitor:
    """The monitor's safety state machine; ``on_abort(reason)`` is called once per abort."""

    def __init__(self, settings: MonitorNodeParams, F_break: float, ratio: float,
                 horizon: float, steady: int, tension_topics: Sequence[str],
                 stamped_topics: Sequence[str],
                 on_abort: Callable[[str], None] = lambda reason: None,
                 n_links: int | None = None):
        self.tension_topics = tuple(tension_topics)   # (link tensions, contact tension)
        self.stamped_topics = tuple(stamped_topics)
        self.on_abort = on_abort
        self.configure(settings, F_break, ratio, horizon, n_links)
        self.reset(steady)

    def configure(self, settings: MonitorNodeParams, F_break: float, ratio: float,
                  horizon: float, n_links: int | None = None) -> None:
        """New settings, F_break [N], abort ratio, trend horizon [s] and the number of links
        a tension sample must have (``sheet.n_masses + 1``; None: any)."""
        self.settings, self.F_break, self.ratio, self.horizon = settings, F_break, ratio, horizon
        self.n_links = n_links

    @property
    def plausible(self) -> tuple[float, float]:
        """(lowest, highest) tension [N] that can be data: below ``-3 noise_sigma`` a link
        would push, above ``max_tension_ratio x F_break`` the sheet would long have torn."""
        s = self.settings
        return -3.0 * s.noise_sigma, s.max_tension_ratio * self.F_break

    @property
    def threshold(self) -> float:
        """F_abort [N]."""
        return self.ratio * self.F_break

    @property
    def ready(self) -> bool:
        return self.state == "ready"

    def reset(self, steady: int) -> None:
        """Re-arm: back to ``waiting``, everything seen so far forgotten."""
        self.state = "waiting"                 # waiting -> ready -> aborted
        self.abort_reason = ""
        #: why the monitor may not become ready yet besides its data ("" none): the node's
        #: checks of the cell, the clock, its twins
        self.blocked = ""
        self._clock_seen = 0                   # the node clock at the newest tick [ns]
        #: staleness on the cell's clock (a lockstep cell), set by the node at each tick
        self.cell_clock = False
        self._rx_clock: dict[str, int] = {}    # topic -> cell time of the newest sample [ns]
        #: the newest state's header stamp [ns] (the profile, published before the tensions
        #: of its step): dates a sample where the best-effort /clock lost its step's messages
        self._state_stamp = 0
        self._start = steady
        self._rx: dict[str, int | None] = {t: None for t in self.tension_topics
                                           + self.stamped_topics}
        self.stamp_age: dict[str, float] = {}
        self._old: dict[str, str] = {}        # topic -> why its newest stamp is too old
        self._old_prev: set[str] = set()      # the same at the previous tick
        self._stale_prev: set[str] = set()    # paced streams stale on the cell's clock then
        self._future: dict[str, tuple[int, int]] = {}   # topic -> (stamp, steady arrival) [ns]
        self.tension = math.nan                # latest largest link tension [N]
        self.link = 0
        self.contact = math.nan                # latest contact tension [N]
        self.F_seen = 0.0                      # largest tension since (re)start [N]
        self._trend = TensionTrend()

    def abort(self, reason: str) -> bool:
        """Abort (once: the first reason latches); True if this call aborted."""
        if self.state == "aborted":
            return False
        self.state, self.abort_reason = "aborted", reason
        self.on_abort(reason)
        return True

    def paced(self, topic: str) -> bool:
        """Whether ``topic`` is judged on the cell's clock: in a lockstep cell
        (:attr:`cell_clock`), the acknowledged link tensions, or every tension stream where
        the monitor does not acknowledge (simulator and monitor on one executor)."""
        return self.cell_clock and (topic == self.tension_topics[0]
                                    or not self.settings.acknowledge)

    def age(self, topic: str, steady: int) -> float:
        """Time [s] since the newest sample on ``topic`` (inf: none yet): on the wall's
        steady clock, or on the cell's clock when :meth:`paced` and the clock has run (a
        sample from before the first /clock dated at the cell's time 0: never younger)."""
        rx = self._rx[topic]
        if rx is None:
            return math.inf
        seen = self._rx_clock.get(topic, 0)
        if self.paced(topic) and self._clock_seen > 0:
            return max(self._clock_seen - seen, 0) / NS
        return (steady - rx) / NS

    def _received(self, topic: str, steady: int) -> None:
        """A sample of ``topic`` arrived: its cell time is the node's clock, or the newest
        state's stamp where that is later (the node's /clock is best effort: two lost /clock
        messages in a row aged a fresh sample by three steps under 5 % UDP loss, a false
        abort in seed 4731's campaign).  In a lockstep cell the simulator publishes no state
        beyond ``monitor_lead`` unacknowledged samples, so the stamp dates the sample to
        within ``monitor_lead - 1`` steps (exactly at the default 1)."""
        self._rx[topic] = steady
        self._rx_clock[topic] = max(self._clock_seen, self._state_stamp)

    # -- data -------------------------------------------------------------------------
    def on_tensions(self, values: Sequence[float], steady: int, clock: int) -> None:
        """The link tensions [N] of one sample."""
        topic = self.tension_topics[0]
        if clock > 0:
            self._clock_seen = clock
        self._received(topic, steady)
        tensions = np.asarray(values, dtype=float)
        if tensions.size == 0:
            self.abort(f"empty {topic} message")
            return
        bad = ~np.isfinite(tensions)
        if bad.any():
            i = int(np.argmax(bad))
            self.abort(f"non-finite tension ({tensions[i]}) in link {i + 1} on {topic}")
            return
        if self.n_links is not None and tensions.size != self.n_links:
            self.abort(f"{topic} has {tensions.size} links, expected {self.n_links} "
                       f"(sheet.n_masses + 1): another sheet or a lying source")
            return
        if self._implausible(tensions, topic):
            return
        i = int(np.argmax(tensions))
        self.tension, self.link = float(tensions[i]), i + 1
        self.F_seen = max(self.F_seen, self.tension)
        self._check(self.tension, f"link {self.link}")
        self._check_trend(self.tension, clock)

    def on_contact(self, value: float, steady: int, clock: int = 0) -> None:
        """The tension [N] at the tool contact, received at ``steady`` and the node clock
        ``clock`` [ns] (0: not known; the newest one seen is taken)."""
        topic = self.tension_topics[1]
        if clock > 0:
            self._clock_seen = clock
        self._received(topic, steady)
        value = float(value)
        if not math.isfinite(value):
            self.abort(f"non-finite contact tension ({value}) on {topic}")
            return
        if self._implausible(np.array([value]), topic, "contact tension"):
            return
        self.contact = value
        self._check(value, "contact tension")

    def _implausible(self, values: np.ndarray, topic: str, what: str = "") -> bool:
        """Abort (True) on a value outside :attr:`plausible`."""
        lo, hi = self.plausible
        bad = (values < lo) | (values > hi)
        if not bad.any():
            return False
        i = int(np.argmax(bad))
        where = what or f"link {i + 1}"
        self.abort(f"implausible tension {values[i]:.6g} N ({where}) on {topic}: expected "
                   f"[{lo:.4g}, {hi:.4g}] N (-3 noise_sigma to max_tension_ratio "
                   f"{self.settings.max_tension_ratio:g} x F_break)")
        return True

    def _check(self, value: float, where: str) -> None:
        if self.state != "aborted" and value >= self.threshold:
            self.abort(f"tension {value:.4f} N ({where}) reached the abort threshold "
                       f"{self.threshold:.4f} N = {self.ratio:.3f} x F_break "
                       f"{self.F_break:g} N")

    @property
    def trend_rate(self) -> float:
        """The largest tension's trend [N/s] (nan: too few samples yet)."""
        return self._trend.rate

    def _check_trend(self, value: float, clock: int) -> None:
        s, now = self.settings, clock / NS
        if now <= 0.0:
            return
        rate = self._trend.add(now, value, s.trend_window, s.trend_min_samples)
        if (s.trend_abort and self.state != "aborted" and rate > 0.0
                and value + rate * self.horizon >= self.threshold):
            self.abort(f"tension trend {rate:.4f} N/s from {value:.4f} N predicts "
                       f"the abort threshold {self.threshold:.4f} N within {self.horizon:.3f} s "
                       f"(detect_time + stop_time)")

    def on_stamped(self, topic: str, stamp: int, steady: int, clock: int,
                   sim_time: bool, owned: bool = True) -> None:
        """A message on a stamped topic with header stamp ``stamp`` [ns]; ``owned``: from the
        bound simulator (only its state's stamp dates the tension samples)."""
        self._rx[topic] = steady
        if stamp == 0:
            self.abort(f"zero header stamp on {topic}")
            return
        if owned and topic == self.stamped_topics[0]:
            self._state_stamp = stamp
        if clock <= 0:
            return                                        # no clock yet (use_sim_time, no /clock)
        age = (clock - stamp) / NS
        self.stamp_age[topic] = age
        if -age > self.settings.stamp_tolerance:
            if sim_time:
                # On simulated time the node's clock is the newest /clock message it has
                # *processed*; a busy process can handle a data message before the /clock
                # messages that arrived with it. The stamp is judged again on the watchdog
                # (steady clock): still ahead after max_data_age -> abort.
                self._future.setdefault(topic, (stamp, steady))
            else:
                self.abort(self._future_reason(topic, -age))
        elif age > self.settings.max_stamp_age:
            # judged at the next tick: a backlog this process read late is followed by fresh
            # stamps that clear it; a stream whose newest stamp stays old aborts
            self._old[topic] = (f"header stamp on {topic} is {age:.3f} s old "
                                f"(max_stamp_age {self.settings.max_stamp_age:g} s)")
        else:
            self._old.pop(topic, None)

    def _future_reason(self, topic: str, ahead: float) -> str:
        return (f"header stamp on {topic} lies {ahead:.3f} s in the future of the node "
                f"clock (stamp_tolerance {self.settings.stamp_tolerance:g} s)")

    def _check_future(self, steady: int, clock: int) -> None:
        """Future stamps held back on simulated time: clear once the clock has caught up,
        abort if one is still ahead after ``max_data_age`` of wall time."""
        for topic, (stamp, arrived) in list(self._future.items()):
            ahead = (stamp - clock) / NS
            if ahead <= self.settings.stamp_tolerance:
                del self._future[topic]
            elif (steady - arrived) / NS > self.settings.max_data_age:
                del self._future[topic]
                self.abort(self._future_reason(topic, ahead)
                           + f", {(steady - arrived) / NS:.3f} s after it arrived")

    def on_deadline(self, topic: str) -> None:
        """The QoS deadline of ``topic`` was missed (a wall-clock deadline: not counted on
        the cell's clock)."""
        if self.state == "ready" and not self.cell_clock:
            self.abort(f"stale data: QoS deadline of {self.settings.max_data_age:g} s "
                       f"missed on {topic}")

    # -- watchdog (steady clock) ------------------------------------------------------
    def tick(self, steady: int, clock: int, stalled: bool = False,
             previous: int | None = None) -> bool:
        """The watchdog: judge staleness and readiness; returns :attr:`ready`.

        ``stalled``: this process stood still for a while (a busy machine), so samples
        may wait unread; a stream that was still fresh at the ``previous`` tick [ns,
        steady] is then judged at the next tick, not now (:class:`StallGuard.excuses`).
        """
        s = self.settings
        self._clock_seen = clock
        if self._future and self.state != "aborted":
            self._check_future(steady, clock)
        ages = {t: self.age(t, steady) for t in self.tension_topics}
        stale = self._stale(steady)
        if stalled and stale:
            # excused only where the stream was fresh at the previous tick
            stale = [t for t in stale if previous is not None and (
                (rx := self._rx[t]) is None or (previous - rx) / NS > s.max_data_age)]
        # an abort on the cell's clock asks a paced stream to be stale at two ticks running:
        # the node's clock is dated at each /clock it reads, the sample at the clock it
        # arrived at, and lost /clock messages (best effort) date it too early until the
        # next sample comes, a tick later at most (with the simulator waiting on its
        # acknowledgements, the cell cannot move unwatched meanwhile); readiness asks fresh
        # data at this tick
        on_cell = {t for t in stale if self.paced(t) and ages[t] > s.max_data_age
                   and self.wall_age(t, steady) <= self._wall_limit}
        abort_on = [t for t in stale if t not in on_cell or t in self._stale_prev]
        self._stale_prev = on_cell
        persist = [t for t in self._old if t in self._old_prev]   # old at two ticks running
        self._old_prev = set(self._old)
        if self.state == "ready" and self._old and (not stalled or persist):
            topic = persist[0] if persist else next(iter(self._old))
            self.abort(f"stale data: {self._old[topic]}")
        elif self.state == "ready" and abort_on:
            t = abort_on[0]
            if self.paced(t) and ages[t] <= s.max_data_age:    # the cell's clock stood still
                self.abort(f"stale data: no {t} for {self.wall_age(t, steady):.3f} s of wall "
                           f"time while the cell's clock stood still: its simulator is lost "
                           f"({LOCKSTEP_WALL_FACTOR:g} x max_data_age {s.max_data_age:g} s)")
            elif self.cell_clock and not self.paced(t):
                self.abort(f"stale data: no {t} for {ages[t]:.3f} s of wall time "
                           f"({LOCKSTEP_WALL_FACTOR:g} x max_data_age {s.max_data_age:g} s: "
                           f"in a lockstep cell the stream not acknowledged is judged on the "
                           f"wall)")
            else:
                self.abort(f"stale data: no {t} for "
                           + (f"{ages[t]:.3f} s" if math.isfinite(ages[t]) else "ever")
                           + f" (max_data_age {s.max_data_age:g} s)")
        elif self.state == "waiting":
            if (not stale and not self._old and not self._future and clock > 0
                    and not self.blocked):
                self.state = "ready"
            elif (steady - self._start) / NS > s.startup_timeout:
                why = ("no " + ", ".join(stale) if stale
                       else next(iter(self._old.values()), "") or self.blocked or "no clock")
                self.abort(f"not ready within startup_timeout {s.startup_timeout:g} s: {why}")
        return self.ready

    def waiting_for(self, steady: int, clock: int) -> str:
        """What a ``waiting`` monitor still lacks ("" when nothing): the node's own checks,
        the clock, the tension streams with no fresh sample."""
        if self.blocked:
            return self.blocked
        if clock <= 0:
            return "no clock yet (use_sim_time: /clock)"
        stale = self._stale(steady)
        return ("no fresh sample on " + ", ".join(stale)) if stale else ""

    def _stale(self, steady: int) -> list[str]:
        """The tension topics whose newest sample is older than ``max_data_age`` (in a
        lockstep cell: on its clock, or beyond the wall's bound)."""
        limit = self.settings.max_data_age
        return [t for t in self.tension_topics
                if (self.age(t, steady) > limit and (self.paced(t) or not self.cell_clock))
                or self.wall_age(t, steady) > self._wall_limit]

    @property
    def _wall_limit(self) -> float:
        """The wall age [s] beyond which a stream is stale whatever the cell's clock."""
        s = self.settings
        return s.max_data_age * (LOCKSTEP_WALL_FACTOR if self.cell_clock else 1.0)

    def wall_age(self, topic: str, steady: int) -> float:
        """Wall time [s] since the newest sample on ``topic`` (inf: none yet)."""
        rx = self._rx[topic]
        return math.inf if rx is None else (steady - rx) / NS

    def diagnostics(self, steady: int) -> tuple[str, str, dict]:
        """(level OK/WARN/ERROR/STALE, message, key values) of the present state."""
        F = self.tension
        if self.state == "aborted":
            level, message = "ERROR", f"aborted: {self.abort_reason}"
        elif self.state == "waiting":
            level, message = "STALE", ("waiting: " + (self.waiting_for(steady, self._clock_seen)
                                                      or "fresh tension data"))
        elif math.isfinite(F) and F >= self.settings.warn_ratio * self.threshold:
            level, message = "WARN", (f"tension {F:.4f} N near the abort threshold "
                                      f"{self.threshold:.4f} N")
        else:
            level, message = "OK", "tension below the abort threshold"
        values = {
            "state": self.state, "tension_max": F, "tension_link": self.link,
            "contact_tension": self.contact, "F_break": self.F_break,
            "abort_threshold": self.threshold,
            "safety_factor": safety_factor(self.F_break, F),
            "largest_tension_seen": self.F_seen, "trend_rate": self.trend_rate,
            **{"data_age_" + t.rsplit("/", 1)[-1]: self.age(t, steady)
               for t in self.tension_topics},
            "stamp_age": max(self.stamp_age.values(), default=math.nan),
            "abort_reason": self.abort_reason,
        }
        return level, message, values
