"""The gap watch node's decisions without ROS (``gapwatch.session.WatchSession``):
what is fed, dropped or kept for a run's start, when a run is diagnosed, the worker's
watchdog and what the reports say.  The clock is injected: waits are exact."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rheo_shaping.gapwatch.floor import ResidualFloor
from rheo_shaping.gapwatch.session import AT_END, ON_WARN, WORKER_STALL, WatchSession
from rheo_shaping.params.config import load_cell
from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams

CELL_FILE = Path(__file__).resolve().parents[2] / "config" / "cell.yaml"


class Clock:
    """A monotonic clock the test moves [s]."""

    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture(scope="module")
def cell():
    return load_cell(CELL_FILE)


@pytest.fixture(scope="module")
def biased(cell):
    """The model's own record with a load-cell bias of 0.04 N: WARN within 20 s."""
    rec, _ = synthesize_record(cell, MeasurementParams(), seed=11)
    assert rec.wrench_xz is not None
    return replace(rec, wrench_xz=rec.wrench_xz + np.array([0.03, -0.04]))


def samples(rec, upto: float = np.inf):
    """The record's samples as the node queues them, in stamp order."""
    out = [("pose", float(t), tuple(map(float, xz))) for t, xz in zip(rec.pose_t, rec.pose_xz)
           if t <= upto]
    out += [("profile", float(t), p) for t, p in zip(rec.profile_t, rec.profiles) if t <= upto]
    out += [("wrench", float(t), tuple(map(float, f)))
            for t, f in zip(rec.wrench_t, rec.wrench_xz) if t <= upto]
    return sorted(out, key=lambda s: s[1])


def session(cell, clock=None, **settings):
    s = GapWatchNodeParams(**settings)
    return WatchSession(cell, ResidualFloor.load(), s, clock or Clock())


def test_samples_before_the_plan_wait_and_only_those_of_the_run_are_fed(cell, biased):
    ws = session(cell, queue_limit=100000)
    for kind, t, v in samples(biased, upto=5.0):
        ws.put(kind, t - 2.0, v)                   # 2 s of the cell at rest before the start
    assert ws.drain() == [] and ws.core is None    # wait_for_plan: nothing is watched yet
    n_early = len(ws.early)
    assert n_early == len(samples(biased, upto=5.0))
    ws.put("start", 0.0, None)
    events = ws.drain()
    assert events == ["OK: process start at stamp 0.000 s: watching a new run"]
    assert ws.core is not None and ws.start_stamp == 0.0 and not ws.early
    # the samples stamped at or after the start were fed, the 2 s before it were not
    fed = sum(1 for _, t, _ in samples(biased, upto=5.0) if t - 2.0 >= 0.0)
    assert len(ws.core.record().pose_t) == sum(1 for k, t, _ in samples(biased, upto=5.0)
                                               if k == "pose" and t - 2.0 >= 0.0)
    assert 0 < fed < n_early
    # an older or equal start is the same run; a later one starts a new run
    ws.put("start", 0.0, None)
    assert ws.drain() == [] and ws.start_stamp == 0.0
    ws.put("start", 7.5, None)
    assert ws.drain() == ["OK: process start at stamp 7.500 s: watching a new run"]


def test_a_sample_that_waited_longer_than_max_lag_is_dropped_and_the_report_says_so(cell, biased):
    clock = Clock()
    ws = session(cell, clock, max_lag=2.0, wait_for_plan=False)
    first, second = samples(biased)[:2]
    ws.put(*first)
    clock.t += 2.5                                   # the worker comes 2.5 s later
    ws.put(*second)
    ws.drain()
    assert ws.dropped["waited longer than max_lag"] == 1
    assert ws.lag["last_s"] == 0.0                   # the second was fed at once
    r = ws.report()
    assert r.level == "WARN"                         # a drop makes OK (or STALE) a WARN
    assert r.message.endswith("; 1 samples dropped (waited longer than max_lag: 1)")
    assert r.body["dropped"]["waited longer than max_lag"] == 1
    received: dict[str, int] = {}
    for kind in (first[0], second[0]):
        received[kind] = received.get(kind, 0) + 1
    assert r.values["dropped"] == 1 and r.body["received"] == received


def test_a_full_queue_drops_the_oldest_and_counts_it(cell, biased):
    ws = session(cell, queue_limit=3)
    for s in samples(biased)[:5]:
        ws.put(*s)
    assert ws.dropped["queue full"] == 2 and len(ws.queue) == 3
    assert ws.report().values["queued"] == 3


def test_a_stuck_worker_is_reported_once_and_nothing_more_is_queued(cell, biased):
    clock = Clock()
    ws = session(cell, clock)
    for s in samples(biased)[:4]:
        ws.put(*s)
    clock.t += WORKER_STALL                          # at the limit: not yet stuck
    assert ws.watchdog() == "" and not ws.stalled
    clock.t += 1.0
    msg = ws.watchdog()
    assert msg == "the model has been stuck on one sample for 31 s: no more samples are queued"
    assert ws.stalled and ws.watchdog() == ""        # once
    assert ws.dropped["the model is stuck"] == 4 and len(ws.queue) == 0
    ws.put(*samples(biased)[5])
    assert ws.dropped["the model is stuck"] == 5 and len(ws.queue) == 0
    r = ws.report()
    assert r.level == "ERROR" and r.message.startswith("the model has been stuck")


def test_a_run_that_warns_is_diagnosed_once_at_its_warn(cell, biased):
    ws = session(cell, wait_for_plan=False, queue_limit=100000)
    assert ws.run_record(busy=False) == (None, "no run yet (no process start seen)")
    whys = []
    feed = samples(biased)
    for i in range(0, len(feed), 50):                # the worker wakes every 50 samples
        for s in feed[i:i + 50]:
            ws.put(*s)
        ws.drain()
        why = ws.due_diagnosis(busy=False)
        if why:
            whys.append((why, ws.core.first_warn))
    assert ws.core is not None and ws.core.first_warn is not None and ws.core.first_warn < 20
    # the WARN once, when it came (the end: the next test)
    assert len(whys) == 1 and whys[0] == (ON_WARN, ws.core.first_warn)
    rec, why_not = ws.run_record(busy=False)
    assert why_not == "" and rec is not None and rec.pose_t.size > 2
    assert ws.run_record(busy=True) == (None, "a diagnosis is running")
    # diagnose_on_warn false: never
    quiet = session(cell, wait_for_plan=False, diagnose_on_warn=False, queue_limit=100000)
    for s in feed:
        quiet.put(*s)
    quiet.drain()
    assert quiet.core is not None and quiet.core.first_warn is not None
    assert quiet.due_diagnosis(busy=False) == ""


def test_the_end_of_a_run_that_warned_waits_for_a_running_diagnosis(cell, biased):
    ws = session(cell, wait_for_plan=False, queue_limit=100000)
    for s in samples(biased):
        ws.put(*s)
    ws.drain()
    assert ws.due_diagnosis(busy=False) == ON_WARN
    ws.core.update(final=True)
    assert ws.core.ended
    assert ws.due_diagnosis(busy=True) == ""         # asked again while one runs
    assert ws.due_diagnosis(busy=False) == AT_END
    assert ws.due_diagnosis(busy=False) == ""        # once per run


def test_a_model_that_raises_is_an_error_on_the_report(cell):
    ws = session(cell)
    msg = ws.failed(RuntimeError("the solver diverged"))
    assert msg == "gap watch failed: RuntimeError: the solver diverged"
    assert ws.report().level == "ERROR"
