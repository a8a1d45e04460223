"""The simulator's output schedule without ROS (rheo_shaping.sheet.cadence): what the node
publishes at each step is what these answer."""
from __future__ import annotations

import math

from rheo_shaping.params.node_params import SimulatorNodeParams
from rheo_shaping.sheet.cadence import Cadence, RateMeter
from rheo_shaping.units import NS

MS = NS // 1000


def _states(c: Cadence, steps_ns) -> list[int]:
    sent = []
    for t in steps_ns:
        if c.state_due(t):
            c.state_sent(t)
            sent.append(t)
    return sent


def test_the_state_goes_out_every_publish_period_of_simulated_time_or_when_forced():
    c = Cadence(SimulatorNodeParams(publish_period=0.05))
    steps = [k * 20 * MS for k in range(11)]               # steps of 20 ms, 0 to 200 ms
    assert _states(c, steps) == [0, 60 * MS, 120 * MS, 180 * MS]
    c.force()
    assert c.state_due(200 * MS) and not c.state_due(200 * MS)   # forced once
    every = Cadence(SimulatorNodeParams(publish_period=0.0))
    assert _states(every, steps) == steps


def test_camera_frames_fall_on_a_grid_of_one_over_the_rate():
    """At 2 Hz, steps of 0.3 s: a frame at the first step at or after 0, 0.5, 1.0, ... s."""
    c = Cadence(SimulatorNodeParams(camera=True, camera_rate=2.0))
    steps = [k * 300 * MS for k in range(8)]               # 0 to 2.1 s
    frames = [t for t in steps if c.camera_due(t)]
    assert frames == [0, 600 * MS, 1200 * MS, 1500 * MS, 2100 * MS]
    off = Cadence(SimulatorNodeParams(camera=False))
    assert not any(off.camera_due(t) for t in steps)


def test_while_the_clock_holds_frames_come_at_the_running_rate_per_wall_second():
    """camera_rate 2 Hz at x10: every 50 ms of the steady clock."""
    c = Cadence(SimulatorNodeParams(camera=True, camera_rate=2.0, real_time_factor=10.0))
    ticks = [k * 10 * MS for k in range(16)]
    assert [t for t in ticks if c.hold_camera_due(t)] == [0, 50 * MS, 100 * MS, 150 * MS]


def test_markers_and_diagnostics_on_the_steady_clock_and_diagnostics_at_once_after_a_hold():
    c = Cadence(SimulatorNodeParams(marker_period=0.1, diagnostics_period=0.5,
                                    publish_markers=True))
    ticks = [k * 50 * MS for k in range(13)]               # 0 to 600 ms
    assert [t for t in ticks if c.markers_due(t)] == [k * 100 * MS for k in range(7)]
    diag = [t for t in ticks if c.diagnostics_due(t)]
    assert diag == [0, 500 * MS]
    c.force(diagnostics=True)
    assert c.diagnostics_due(610 * MS)
    quiet = Cadence(SimulatorNodeParams(publish_markers=False))
    assert not quiet.markers_due(0)


def test_progress_lines_every_period_of_process_time_of_a_started_run():
    c = Cadence(SimulatorNodeParams(progress_period=10.0))
    assert not c.progress_due(12.0, started=False)
    times = [0.0, 5.0, 10.0, 12.0, 31.0, 39.0, 40.0]
    assert [t for t in times if c.progress_due(t, started=True)] == [10.0, 31.0, 40.0]
    c.restart()                                           # a new run: from its start again
    assert c.progress_due(10.0, started=True)
    never = Cadence(SimulatorNodeParams(progress_period=0.0))
    assert not never.progress_due(100.0, started=True)


def test_the_achieved_factor_is_simulated_over_steady_time_between_readings():
    r = RateMeter(wanted=10.0)
    assert math.isnan(r.measure(0, 0))
    assert r.measure(1 * NS, 10 * NS) == 10.0 and not r.lagging()
    assert r.measure(2 * NS, 14 * NS) == 4.0 and r.lagging()        # under half of x10
