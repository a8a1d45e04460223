"""When a simulator's outputs are due, without ROS (docs/ros.md, the simulator's parameters).

:class:`Cadence` decides, for the ``simulator`` node (which only publishes what it is told
is due), when each output goes out:

* the sheet's state (profile, tensions, pose, wrench) every ``publish_period`` of simulated
  time, or at once when forced (a hold, a step that changed the state out of turn);
* the simulated camera's frames on a grid of ``1 / camera_rate`` of simulated time (each at
  the first step at or after its grid time), and while ``/clock`` holds, at the rate they
  come at when running (``camera_rate x real_time_factor`` per wall second);
* markers every ``marker_period`` and ``/diagnostics`` every ``diagnostics_period`` of the
  steady clock (``/diagnostics`` at once after a hold);
* a progress line every ``progress_period`` of process time.

:class:`RateMeter` measures the achieved real-time factor between two diagnostics.
Periods are read from the settings at each call (``publish_period``, ``publish_markers``,
``diagnostics_period`` are tunable while the node runs).  Times are integer nanoseconds:
``t_ns`` simulated (or node) time, ``steady`` a steady clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..params.node_params import SimulatorNodeParams
from ..units import NS


@dataclass
class Cadence:
    """The simulator's output schedule; each ``*_due`` call that answers True counts the
    output as sent."""

    settings: SimulatorNodeParams
    last_state_ns: int | None = None          # simulated time of the last state [ns]
    forced: bool = False                      # the next state goes out whatever the period
    next_camera_ns: int | None = None         # the next frame's grid time [ns]
    last_marker: int | None = None            # steady time of the last markers [ns]
    last_diagnostics: int | None = None       # steady time of the last /diagnostics [ns]
    last_hold_camera: int | None = None       # steady time of the last frame while held [ns]
    next_progress_s: float = field(init=False)   # process time of the next progress line [s]

    def __post_init__(self) -> None:
        self.restart()

    def restart(self) -> None:
        """A new run: progress lines from its start again."""
        self.next_progress_s = self.settings.progress_period

    def force(self, diagnostics: bool = False) -> None:
        """The next state goes out at once (and ``/diagnostics`` too, ``diagnostics``)."""
        self.forced = True
        if diagnostics:
            self.last_diagnostics = None

    def state_due(self, t_ns: int) -> bool:
        """The state at ``t_ns`` [ns]: due every ``publish_period`` (0: every step), forced,
        or the first."""
        period = self.settings.publish_period
        due = (self.last_state_ns is None or period == 0.0 or self.forced
               or t_ns - self.last_state_ns >= period * NS - 1)
        if due:
            self.forced = False
        return due

    def state_sent(self, t_ns: int) -> None:
        """A state stamped ``t_ns`` [ns] went out (also out of turn)."""
        self.last_state_ns = t_ns

    def camera_due(self, t_ns: int) -> bool:
        """A frame at ``t_ns`` [ns]: the first step at or after each grid time."""
        s = self.settings
        if not s.camera or s.camera_rate <= 0.0:
            return False
        if self.next_camera_ns is not None and t_ns < self.next_camera_ns:
            return False
        period = int(round(NS / s.camera_rate))
        self.next_camera_ns = (t_ns // period + 1) * period
        return True

    def hold_camera_due(self, steady: int) -> bool:
        """A frame of the waiting sheet while ``/clock`` holds, at ``steady`` [ns]."""
        s = self.settings
        if not s.camera or s.camera_rate <= 0.0:
            return False
        period = NS / (s.camera_rate * s.real_time_factor)
        if self.last_hold_camera is not None and steady - self.last_hold_camera < period:
            return False
        self.last_hold_camera = steady
        return True

    def markers_due(self, steady: int) -> bool:
        s = self.settings
        if not s.publish_markers or (self.last_marker is not None
                                     and steady - self.last_marker < s.marker_period * NS):
            return False
        self.last_marker = steady
        return True

    def diagnostics_due(self, steady: int) -> bool:
        if (self.last_diagnostics is not None
                and steady - self.last_diagnostics < self.settings.diagnostics_period * NS):
            return False
        self.last_diagnostics = steady
        return True

    def progress_due(self, t_s: float, started: bool) -> bool:
        """A progress line at process time ``t_s`` [s] of a started run."""
        period = self.settings.progress_period
        if period <= 0 or not started or t_s < self.next_progress_s:
            return False
        while self.next_progress_s <= t_s:
            self.next_progress_s += period
        return True


@dataclass
class RateMeter:
    """The achieved real-time factor: simulated over steady time between two readings."""

    wanted: float                               # the real_time_factor asked for
    factor: float = math.nan                    # the newest achieved factor
    _ref: tuple[int, int] | None = None         # (steady, simulated) of the last reading [ns]

    def measure(self, steady: int, t_ns: int) -> float:
        """Read the clocks [ns]; the factor since the last reading (nan: the first)."""
        if self._ref is not None and steady > self._ref[0]:
            self.factor = (t_ns - self._ref[1]) / (steady - self._ref[0])
        self._ref = (steady, t_ns)
        return self.factor

    def lagging(self) -> bool:
        """Whether the cell runs at under half the factor asked for."""
        return self.factor < 0.5 * self.wanted
