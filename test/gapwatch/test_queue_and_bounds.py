"""The gap watch's queue shared by the executor's callbacks and the worker thread
(rheo_shaping.gapwatch.queue.SampleQueue), and the bounds of what its intake takes."""
from __future__ import annotations

import threading

import pytest

from rheo_shaping.gapwatch.intake import MAX_FORCE, MAX_POSITION
from rheo_shaping.gapwatch.queue import SampleQueue


def test_publisher_and_worker_against_each_other_never_see_a_torn_queue():
    """A report read the queue's length and then its first sample while the worker popped
    it (an IndexError left rclpy.spin).  Here a filler, a drainer and a reader run against
    each other for 200,000 samples: every sample is popped once, in order, none lost."""
    q = SampleQueue(limit=10**6)
    n = 200_000
    popped: list[int] = []
    errors: list[BaseException] = []
    done = threading.Event()

    def fill():
        for i in range(n):
            q.put(("pose", float(i), None), now=float(i))
        done.set()

    def drain():
        while not (done.is_set() and len(q) == 0):
            item = q.pop()
            if item is not None:
                popped.append(int(item[1]))

    def read():
        try:
            while not done.is_set() or len(q):
                count, age = q.waiting(now=float(n))
                assert count >= 0 and (age >= 0.0 if count else age == 0.0)
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=f) for f in (fill, drain, read)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors
    assert popped == list(range(n))


def test_at_its_limit_the_oldest_sample_goes_first():
    q = SampleQueue(limit=3)
    assert [q.put((k, 0.0, None), now=1.0) for k in "abcd"] == [False, False, False, True]
    assert [q.pop()[0] for _ in range(3)] == ["b", "c", "d"] and q.pop() is None
    assert q.waiting(5.0) == (0, 0.0)
    q.put(("e", 0.0, None), now=2.0)
    assert q.waiting(5.0) == (1, 3.0)
    assert q.clear() == 1 and len(q) == 0
    with pytest.raises(ValueError, match="queue limit = 0"):
        SampleQueue(0)


def test_the_intake_refuses_poses_points_and_forces_out_of_any_cell():
    """One /tool/pose at 1e300 m sent the model into a loop it never left."""
    from rheo_shaping.gapwatch.watch import GapWatch
    from rheo_shaping.gapwatch.floor import ResidualFloor
    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
    w = GapWatch(CellParams(), ResidualFloor.load(), GapWatchNodeParams())
    w.start(0.0)
    assert "farther than 10 m" in w.pose(0.1, 1e300, 0.0)
    assert "farther than 10 m" in w.pose(0.1, 0.0, -(MAX_POSITION * (1 + 1e-12)))
    assert w.pose(0.1, MAX_POSITION, 0.0) is None                 # the bound itself is taken
    assert "a point farther than 10 m" in w.profile(0.2, [[0, 0], [0.1, 0], [1e300, 0]])
    assert "beyond 10000 N" in w.wrench(0.2, 0.0, MAX_FORCE * 2)
    assert w.wrench(0.2, 0.0, -MAX_FORCE) is None
