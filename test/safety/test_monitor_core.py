"""The monitor's abort rules, without ROS (rheo_shaping.safety.monitor.TensionMonitor).

Every rule the ``monitor`` node enforces is decided here; test/nodes/test_monitor_node.py
checks that the node feeds it over DDS.  Times are integer nanoseconds.
"""
from __future__ import annotations

import math
from dataclasses import replace

import pytest

from rheo_shaping.params.node_params import MonitorNodeParams
from rheo_shaping.safety.monitor import TensionMonitor, stale_on_cell_clock
from rheo_shaping.units import NS

TENSIONS, CONTACT = "/sheet/tensions", "/sheet/contact_tension"
PROFILE, WRENCH = "/sheet/profile", "/tool/wrench"
F_BREAK, RATIO, HORIZON = 1.04, 0.9, 0.3          # N, -, s
THRESHOLD = RATIO * F_BREAK                       # 0.936 N
T0 = 1_000 * NS                                   # steady clock at start
C0 = 50 * NS                                      # node clock at start


class Harness:
    """A monitor and the two clocks, advanced together."""

    def __init__(self, **settings):
        self.s = replace(MonitorNodeParams(abort_ratio=RATIO), **settings)
        self.aborts: list[str] = []
        self.steady, self.clock = T0, C0
        self.mon = TensionMonitor(self.s, F_BREAK, RATIO, HORIZON, self.steady,
                                  (TENSIONS, CONTACT), (PROFILE, WRENCH),
                                  on_abort=self.aborts.append)

    def advance(self, dt: float) -> None:
        self.steady += int(dt * NS)
        self.clock += int(dt * NS)

    def sample(self, tension: float = 0.1, contact: float = 0.05, dt: float = 0.01) -> None:
        self.advance(dt)
        self.mon.on_tensions([0.5 * tension, tension], self.steady, self.clock)
        self.mon.on_contact(contact, self.steady)

    def make_ready(self) -> None:
        self.sample()
        assert self.mon.tick(self.steady, self.clock)
        assert self.mon.state == "ready" and not self.aborts


def test_waits_then_becomes_ready_on_fresh_data():
    h = Harness()
    assert h.mon.state == "waiting" and not h.mon.tick(h.steady, h.clock)
    h.sample()
    assert h.mon.tick(h.steady, h.clock) and h.mon.ready
    level, _, values = h.mon.diagnostics(h.steady)
    assert level == "OK" and values["tension_max"] == pytest.approx(0.1)
    assert values["tension_link"] == 2 and values["safety_factor"] == pytest.approx(10.4)
    assert values["data_age_tensions"] == 0.0 and values["data_age_contact_tension"] == 0.0


def test_no_clock_is_not_ready():
    h = Harness()
    h.sample()
    assert not h.mon.tick(h.steady, 0) and h.mon.state == "waiting"


@pytest.mark.parametrize("where", ["link", "contact"])
def test_threshold_aborts_at_f_abort_and_not_below(where):
    h = Harness()
    h.make_ready()
    below = math.nextafter(THRESHOLD, 0.0)
    h.sample(tension=below) if where == "link" else h.sample(contact=below)
    assert h.mon.ready and not h.aborts
    h.sample(tension=THRESHOLD) if where == "link" else h.sample(contact=THRESHOLD)
    assert h.mon.state == "aborted" and len(h.aborts) == 1
    assert ("link 2" if where == "link" else "contact tension") in h.aborts[0]
    assert "0.9360 N = 0.900 x F_break 1.04 N" in h.aborts[0]


def test_warn_level_near_the_threshold():
    h = Harness(warn_ratio=0.8)
    h.make_ready()
    h.sample(tension=0.8 * THRESHOLD + 1e-6)
    assert h.mon.diagnostics(h.steady)[0] == "WARN"


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_tension_aborts(bad):
    h = Harness()
    h.make_ready()
    h.mon.on_tensions([0.1, bad, 0.2], h.steady, h.clock)
    assert h.aborts == [f"non-finite tension ({bad}) in link 2 on {TENSIONS}"]
    h2 = Harness()
    h2.mon.on_contact(bad, h2.steady)
    assert h2.aborts == [f"non-finite contact tension ({bad}) on {CONTACT}"]


def test_empty_tensions_abort():
    h = Harness()
    h.mon.on_tensions([], h.steady, h.clock)
    assert h.aborts == [f"empty {TENSIONS} message"]


def _ramp(h: Harness, start: float, rate: float, n: int, dt: float = 0.05) -> None:
    for k in range(n):
        h.sample(tension=start + rate * k * dt, dt=dt)


def test_trend_predicts_the_threshold_only_when_enabled():
    # 0.5 N/s from 0.60 N, a sample every 0.05 s; the fit needs a span of window / 2 =
    # 0.5 s: at 0.85 N (< 0.936 N) it predicts 0.85 + 0.5 x 0.3 s = 1.0 N >= 0.936 N
    for enabled in (False, True):
        h = Harness(trend_abort=enabled, trend_window=1.0, trend_min_samples=4)
        h.make_ready()
        h.advance(2.0)                    # the ready sample leaves the window
        _ramp(h, 0.60, 0.5, 10)           # span 0.45 s: no trend yet
        assert math.isnan(h.mon.trend_rate) and not h.aborts
        h.sample(tension=0.85, dt=0.05)   # span 0.5 s
        assert h.mon.trend_rate == pytest.approx(0.5, rel=1e-6)
        if enabled:
            assert len(h.aborts) == 1 and "tension trend 0.5000 N/s from 0.8500 N" in h.aborts[0]
            assert "within 0.300 s (detect_time + stop_time)" in h.aborts[0]
        else:
            assert not h.aborts and h.mon.ready


def test_trend_restarts_when_the_clock_goes_back():
    h = Harness(trend_abort=True)
    h.make_ready()
    h.advance(2.0)
    _ramp(h, 0.60, 0.5, 8)
    h.clock -= 10 * NS                        # e.g. a simulation restarted
    h.sample(tension=0.85)
    assert math.isnan(h.mon.trend_rate) and not h.aborts


def test_falling_trend_does_not_abort():
    h = Harness(trend_abort=True)
    h.make_ready()
    h.advance(2.0)
    _ramp(h, 0.9, -0.5, 20)
    assert not h.aborts and h.mon.trend_rate == pytest.approx(-0.5, rel=1e-6)


def test_zero_stamp_aborts():
    h = Harness()
    h.mon.on_stamped(PROFILE, 0, h.steady, h.clock, sim_time=False)
    assert h.aborts == [f"zero header stamp on {PROFILE}"]


def test_future_stamp_aborts_at_once_on_wall_time():
    h = Harness(stamp_tolerance=0.05)
    h.make_ready()
    h.mon.on_stamped(WRENCH, h.clock + int(0.04 * NS), h.steady, h.clock, sim_time=False)
    assert not h.aborts
    h.mon.on_stamped(WRENCH, h.clock + int(0.2 * NS), h.steady, h.clock, sim_time=False)
    assert len(h.aborts) == 1 and "lies 0.200 s in the future" in h.aborts[0]


def test_future_stamp_on_sim_time_waits_for_the_clock():
    h = Harness(stamp_tolerance=0.05, max_data_age=0.5)
    h.make_ready()
    stamp = h.clock + int(0.3 * NS)
    h.mon.on_stamped(PROFILE, stamp, h.steady, h.clock, sim_time=True)
    assert not h.aborts
    h.sample(dt=0.1)                          # the clock catches up by 0.1 s, not enough
    h.mon.tick(h.steady, h.clock)
    assert not h.aborts
    h.clock = stamp                           # /clock handled: caught up -> cleared
    h.mon.tick(h.steady, h.clock)
    assert not h.aborts and h.mon.ready
    # a stamp that stays ahead for more than max_data_age of steady time: abort
    h.mon.on_stamped(PROFILE, h.clock + int(5 * NS), h.steady, h.clock, sim_time=True)
    for _ in range(5):
        h.sample(dt=0.09)
        h.steady += int(0.01 * NS)
        h.mon.tick(h.steady, h.clock)
    assert not h.aborts                       # 0.5 s after arrival, not more
    h.sample(dt=0.02)
    h.mon.tick(h.steady, h.clock)
    assert len(h.aborts) == 1 and "in the future" in h.aborts[0]
    assert "after it arrived" in h.aborts[0]


def test_old_stamp_blocks_ready_and_aborts_when_ready():
    h = Harness(max_stamp_age=2.0, startup_timeout=1.0)
    h.sample()
    h.mon.on_stamped(PROFILE, h.clock - 3 * NS, h.steady, h.clock, sim_time=False)
    assert not h.mon.tick(h.steady, h.clock) and not h.aborts      # fault: not ready
    h.mon.on_stamped(PROFILE, h.clock, h.steady, h.clock, sim_time=False)
    assert h.mon.tick(h.steady, h.clock)                            # fresh stamp: ready
    h.mon.on_stamped(PROFILE, h.clock - 3 * NS, h.steady, h.clock, sim_time=False)
    assert not h.aborts                        # judged at the watchdog's next tick
    h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"stale data: header stamp on {PROFILE} is 3.000 s old "
                        f"(max_stamp_age 2 s)"]


def test_an_old_stamp_read_late_from_a_backlog_is_cleared_by_the_fresh_ones_behind_it():
    h = Harness(max_stamp_age=2.0)
    h.make_ready()
    h.mon.on_stamped(WRENCH, h.clock - 3 * NS, h.steady, h.clock, sim_time=False)
    h.mon.on_stamped(WRENCH, h.clock, h.steady, h.clock, sim_time=False)
    h.sample()
    assert h.mon.tick(h.steady, h.clock) and not h.aborts
    # an old newest stamp is excused at a tick after a stall of this process, not twice
    h.mon.on_stamped(WRENCH, h.clock - 3 * NS, h.steady, h.clock, sim_time=False)
    h.sample()
    assert h.mon.tick(h.steady, h.clock, stalled=True) and not h.aborts
    h.sample()
    h.mon.tick(h.steady, h.clock, stalled=True)
    assert h.aborts and "header stamp on" in h.aborts[0]


def test_a_process_stalled_at_every_tick_still_finds_a_dead_stream():
    """The stall excuses a stream only when it was fresh at the previous tick."""
    h = Harness(max_data_age=0.5)
    h.make_ready()
    previous = h.steady
    h.advance(0.4)                                   # stalled tick, data 0.4 s old: fine
    assert h.mon.tick(h.steady, h.clock, stalled=True, previous=previous)
    previous = h.steady
    h.advance(0.4)                                   # 0.8 s old, fresh at the previous tick
    assert h.mon.tick(h.steady, h.clock, stalled=True, previous=previous) and not h.aborts
    previous = h.steady
    h.advance(0.4)                                   # 1.2 s old, 0.8 s at the previous tick
    h.mon.tick(h.steady, h.clock, stalled=True, previous=previous)
    assert h.aborts and h.aborts[0].startswith("stale data: no ")


def test_stale_tensions_abort_one_period_after_max_data_age():
    h = Harness(max_data_age=0.5)
    h.make_ready()
    h.advance(0.5)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts           # exactly 0.5 s: fresh
    h.advance(0.01)
    assert not h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"stale data: no {TENSIONS} for 0.510 s (max_data_age 0.5 s)"]


def test_a_stalled_process_judges_staleness_at_the_next_tick():
    h = Harness(max_data_age=0.5)
    h.make_ready()
    h.advance(0.8)
    assert h.mon.tick(h.steady, h.clock, stalled=True) and not h.aborts
    h.sample()                                # the samples that waited are read now
    h.mon.tick(h.steady, h.clock)
    assert h.mon.ready and not h.aborts
    h.advance(0.8)
    h.mon.tick(h.steady, h.clock, stalled=True)
    h.mon.tick(h.steady, h.clock)             # still nothing: a stream that stopped
    assert len(h.aborts) == 1 and "stale data" in h.aborts[0]


def test_in_a_lockstep_cell_a_starved_machine_slows_the_cell_and_stale_is_on_its_clock():
    """On the cell's clock (the simulator steps only on this monitor's acknowledgements):
    5 s of wall with the cell's clock standing still is no fault (nothing moved), and a
    missed wall-clock QoS deadline neither; beyond 10 x max_data_age of wall the simulator
    is lost; the cell's clock running 0.51 s past the newest sample is stale."""
    h = Harness(max_data_age=0.5)
    h.mon.cell_clock = True
    h.make_ready()
    h.steady += 5 * NS                               # the wall runs, the cell stands still
    assert h.mon.tick(h.steady, h.clock) and not h.aborts
    h.mon.on_deadline(TENSIONS)
    assert not h.aborts
    h.steady += int(0.01 * NS)                       # beyond 10 x max_data_age: lost
    assert not h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"stale data: no {TENSIONS} for 5.010 s of wall time while the cell's "
                        f"clock stood still: its simulator is lost (10 x max_data_age 0.5 s)"]
    h = Harness(max_data_age=0.5)
    h.mon.cell_clock = True
    h.make_ready()
    h.steady += 4 * NS
    h.clock += int(0.5 * NS)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts           # 0.5 s of cell: fresh
    h.clock += int(0.01 * NS)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts     # stale at one tick: judged again
    h.steady += int(0.05 * NS)
    assert not h.mon.tick(h.steady, h.clock)                   # at two ticks running
    assert h.aborts == [f"stale data: no {TENSIONS} for 0.510 s (max_data_age 0.5 s)"]


def test_in_a_lockstep_cell_a_sample_from_before_the_first_clock_is_aged_on_the_cell():
    """The attack campaign's seed 4753, run 96 (x10, load 10-15): the link tensions' newest
    sample had arrived before the monitor's first /clock (no cell time to date it), the
    cell's clock then held for the start, and the starved simulator's next re-publication
    came 0.56 s of wall later; the sample was aged on the wall and the monitor aborted
    before the start.  Such a sample is dated at the cell's time 0 (never younger than it
    is): the held clock keeps it fresh, the running clock ages it, the wall's bound holds."""
    h = Harness(max_data_age=0.5)
    h.mon.cell_clock = True
    h.clock = 0                                      # no /clock yet
    h.steady += int(0.01 * NS)
    h.mon.on_tensions([0.05, 0.1], h.steady, 0)
    h.mon.on_contact(0.05, h.steady)
    h.clock = int(0.1 * NS)                          # the first step's /clock, then held
    assert h.mon.tick(h.steady, h.clock) and h.mon.state == "ready"
    for _ in range(6):                               # 0.9 s of wall: the cell stands still
        h.steady += int(0.15 * NS)
        h.mon.on_contact(0.05, h.steady)
        assert h.mon.tick(h.steady, h.clock) and not h.aborts
    h.clock = int(0.55 * NS)                         # the cell runs: 0.55 s past time 0
    h.mon.tick(h.steady, h.clock)
    h.steady += int(0.01 * NS)
    assert not h.mon.tick(h.steady, h.clock)         # stale at two ticks running
    assert h.aborts == [f"stale data: no {TENSIONS} for 0.550 s (max_data_age 0.5 s)"]


def test_on_the_cells_clock_lost_clock_messages_do_not_age_the_tensions():
    """The node's /clock is best effort: two lost /clock messages in a row (5 % UDP loss,
    seed 4731's false abort) left the monitor at the clock of two steps back while the link
    tensions of those steps arrived; the next /clock then aged the newest sample by three
    steps of 0.2 s (x20), 0.6 s > max_data_age.  The state's stamp (the profile, published
    before the tensions of its step) dates the sample instead, and the cell's clock counts
    only at two ticks running (the next sample clears a date too early); a stream that
    truly stops while the clock runs on is still stale."""
    step = int(0.2 * NS)

    def two_lost_clocks(owned: bool) -> Harness:
        h = Harness(max_data_age=0.5)
        h.mon.cell_clock = True
        h.make_ready()
        for k in (1, 2):                             # /clock of these steps lost
            h.steady += int(0.01 * NS)
            h.mon.on_stamped(PROFILE, h.clock + k * step, h.steady, h.clock, True, owned)
            h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
        h.steady += int(0.01 * NS)
        h.clock += 3 * step                          # the next /clock, before its tensions
        h.mon.tick(h.steady, h.clock)
        return h

    h = two_lost_clocks(owned=True)
    assert h.mon.ready and not h.aborts
    assert h.mon.age(TENSIONS, h.steady) == pytest.approx(0.2)
    h.clock += 2 * step                              # no sample for 0.6 s of the cell's clock
    assert h.mon.tick(h.steady, h.clock)
    h.steady += int(0.05 * NS)                       # ... at two ticks running: stale
    assert not h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"stale data: no {TENSIONS} for 0.600 s (max_data_age 0.5 s)"]
    # a profile from another writer dates nothing: 0.6 s at that tick (the false abort of
    # the code before), and the step's sample, which comes before the next tick, clears it
    h = two_lost_clocks(owned=False)
    assert h.mon.age(TENSIONS, h.steady) == pytest.approx(0.6)
    assert h.mon.ready and not h.aborts
    h.steady += int(0.001 * NS)
    h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
    h.steady += int(0.05 * NS)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts


def test_a_stream_stale_on_the_cells_clock_keeps_a_waiting_monitor_waiting():
    """The two ticks are asked only of an abort: a monitor whose paced stream is stale on
    the cell's clock at its first look does not become ready on it."""
    h = Harness(max_data_age=0.5)
    h.mon.cell_clock = True
    h.sample()
    h.clock += int(0.6 * NS)
    assert not h.mon.tick(h.steady, h.clock)
    assert h.mon.state == "waiting" and not h.aborts


def test_on_the_cells_clock_a_sample_is_aged_from_the_clock_it_arrived_at():
    """A contact sample read before its step's tensions, 0.45 s of cell time after the last
    tick, is 0.1 s old 0.1 s later (not 0.55 s: the clock of the tick before); the
    one-process cell (no acknowledgements: both streams on the cell's clock)."""
    h = Harness(max_data_age=0.5, acknowledge=False)
    h.mon.cell_clock = True
    h.make_ready()
    h.clock += int(0.45 * NS)
    h.steady += int(0.02 * NS)
    h.mon.on_contact(0.05, h.steady, h.clock)
    h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
    h.clock += int(0.1 * NS)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts


def test_where_the_monitor_acknowledges_the_contact_tension_is_judged_on_the_wall_only():
    """The contact tension holds no simulator: 0.6 s of cell time (60 ms of wall at x10)
    behind the acknowledged link tensions is no fault (a delivery late against the cell's
    clock; the link tensions include the contact's link); 5.01 s of wall without one is."""
    h = Harness(max_data_age=0.5)                     # acknowledge: True (the default)
    h.mon.cell_clock = True
    h.make_ready()
    for _ in range(12):                              # 12 steps of 0.05 s at x10
        h.steady += int(0.005 * NS)
        h.clock += int(0.05 * NS)
        h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
    assert h.mon.age(CONTACT, h.steady) == pytest.approx(0.06)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts
    h.steady += int(4.9 * NS)                        # the link tensions go on, the contact not
    h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
    assert h.mon.tick(h.steady, h.clock) and not h.aborts
    h.steady += int(0.05 * NS)
    h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
    assert not h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"stale data: no {CONTACT} for 5.010 s of wall time (10 x max_data_age "
                        f"0.5 s: in a lockstep cell the stream not acknowledged is judged on "
                        f"the wall)"]
    # the one-process cell (no acknowledgements): the same 0.6 s of cell time is stale
    h = Harness(max_data_age=0.5, acknowledge=False)
    h.mon.cell_clock = True
    h.make_ready()
    for _ in range(12):
        h.steady += int(0.005 * NS)
        h.clock += int(0.05 * NS)
        h.mon.on_tensions([0.05, 0.1], h.steady, h.clock)
    assert h.mon.tick(h.steady, h.clock)
    h.steady += int(0.005 * NS)
    assert not h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"stale data: no {CONTACT} for 0.600 s (max_data_age 0.5 s)"]


@pytest.mark.parametrize("sim_time, acknowledge, stale_clock, expected", [
    (True, True, "auto", True), (False, True, "auto", False), (True, False, "auto", False),
    (True, True, "wall", False), (True, False, "cell", True), (False, False, "cell", False)])
def test_the_cells_clock_is_used_only_where_the_cell_waits_for_the_monitor(
        sim_time, acknowledge, stale_clock, expected):
    s = MonitorNodeParams(acknowledge=acknowledge, stale_clock=stale_clock)
    assert stale_on_cell_clock(s, sim_time) is expected


def test_missed_deadline_aborts_only_when_ready():
    h = Harness(max_data_age=0.5)
    h.mon.on_deadline(TENSIONS)
    assert not h.aborts and h.mon.state == "waiting"
    h.make_ready()
    h.mon.on_deadline(CONTACT)
    assert h.aborts == [f"stale data: QoS deadline of 0.5 s missed on {CONTACT}"]


def test_startup_timeout():
    h = Harness(startup_timeout=2.0)
    h.advance(2.0)
    h.mon.tick(h.steady, h.clock)
    assert not h.aborts
    h.advance(0.01)
    h.mon.tick(h.steady, h.clock)
    assert h.aborts == [f"not ready within startup_timeout 2 s: no {TENSIONS}, {CONTACT}"]
    h2 = Harness(startup_timeout=1.0)
    h2.sample()
    h2.advance(1.0)
    h2.mon.on_contact(0.1, h2.steady)
    h2.mon.on_tensions([0.1], h2.steady, h2.clock)
    h2.mon.tick(h2.steady, 0)                 # fresh data but no clock
    h2.advance(0.01)
    h2.mon.tick(h2.steady, 0)
    assert h2.aborts == ["not ready within startup_timeout 1 s: no clock"]


def test_abort_latches_until_reset():
    h = Harness()
    h.make_ready()
    h.sample(tension=2.0)
    h.sample(tension=math.nan)                # a second fault: no second abort, same reason
    h.mon.on_deadline(TENSIONS)
    h.sample(tension=0.1)
    assert len(h.aborts) == 1 and h.mon.state == "aborted" and "2.0000 N" in h.aborts[0]
    assert not h.mon.tick(h.steady, h.clock) and h.mon.diagnostics(h.steady)[0] == "ERROR"
    assert h.mon.F_seen == 2.0
    h.mon.reset(h.steady)
    assert h.mon.state == "waiting" and h.mon.abort_reason == "" and h.mon.F_seen == 0.0
    h.aborts.clear()
    h.make_ready()


def test_configure_moves_the_threshold():
    h = Harness()
    h.make_ready()
    h.mon.configure(h.s, F_BREAK, 0.5, HORIZON)
    assert h.mon.threshold == pytest.approx(0.52)
    h.sample(tension=0.52)
    assert h.aborts and "0.5200 N = 0.500 x F_break" in h.aborts[0]


# -- plausible data only (issue 27: a lying source) -----------------------------------
@pytest.mark.parametrize("values, why", [
    ([0.1], "has 1 links, expected 3"),
    ([0.1] * 100_000, "has 100000 links, expected 3"),
    ([0.1, -5.0, 0.1], "implausible tension -5 N (link 2)"),
    ([0.1, -1e300, 0.1], "implausible tension -1e+300 N (link 2)"),
    ([0.1, 0.2, 10.5], "implausible tension 10.5 N (link 3)"),
])
def test_a_sample_of_the_wrong_length_negative_or_huge_aborts_with_the_reason(values, why):
    h = Harness()
    h.mon.configure(h.s, F_BREAK, RATIO, HORIZON, n_links=3)
    h.mon.on_tensions([0.1, 0.2, 0.1], h.steady, h.clock)
    h.mon.on_contact(0.05, h.steady)
    assert h.mon.tick(h.steady, h.clock)
    h.advance(0.01)
    h.mon.on_tensions(values, h.steady, h.clock)
    assert h.mon.state == "aborted" and len(h.aborts) == 1
    assert why in h.aborts[0], h.aborts[0]


def test_the_plausible_band_is_minus_three_sigma_to_max_tension_ratio_times_F_break():
    h = Harness(noise_sigma=0.005, max_tension_ratio=10.0)
    lo, hi = h.mon.plausible
    assert lo == pytest.approx(-0.015) and hi == pytest.approx(10.4)
    h.make_ready()
    h.mon.on_tensions([-0.0149, 0.2], h.steady, h.clock)      # load-cell noise around 0: data
    h.mon.on_contact(-0.0149, h.steady)
    assert h.mon.state == "ready"
    h.mon.on_contact(-0.016, h.steady)
    assert h.mon.state == "aborted" and "contact tension" in h.aborts[0]


def test_a_waiting_monitor_says_what_it_waits_for():
    h = Harness()
    assert h.mon.waiting_for(h.steady, 0) == "no clock yet (use_sim_time: /clock)"
    assert h.mon.waiting_for(h.steady, h.clock) == (
        "no fresh sample on /sheet/tensions, /sheet/contact_tension")
    h.mon.blocked = "waiting for the simulator's cell on /shaping/cell"
    assert h.mon.waiting_for(h.steady, h.clock) == h.mon.blocked
    h.mon.tick(h.steady, h.clock)
    level, message, _ = h.mon.diagnostics(h.steady)
    assert level == "STALE" and message == "waiting: " + h.mon.blocked
