"""The record that record-cell assembles from what it received (no ROS): t = 0 at the
process start, the state at rest before it kept when the first sample after it is late, and
a clear error for what cannot be a record."""
from __future__ import annotations

import numpy as np
import pytest

from rheo_shaping.params.cell import CellParams
from rheo_shaping.records.assembly import CellBuffer, RecordCellError, assemble
from rheo_shaping.units import NS

T0 = 1_000 * NS                 # the process start on the cell's clock [ns]


def _buffer(late_ns: int = 0, rest: bool = True) -> CellBuffer:
    b = CellBuffer(start_ns=T0, start_xz=(0.03, 0.06))
    home = (0.03, 0.06) if rest else (0.05, 0.06)
    b.pose = [(T0 - 50_000_000, *home)] + [(T0 + late_ns + k * 20_000_000, 0.03, 0.06 - 1e-4 * k)
                                           for k in range(10)]
    frame = np.array([[0.0, 0.06], [0.03, 0.03], [0.06, 0.0]])
    b.profile = [(T0 - 100_000_000, frame)] + [(T0 + late_ns + k * 100_000_000, frame)
                                               for k in range(3)]
    b.wrench = [(T0 + late_ns + k * 20_000_000, 0.0, -0.1) for k in range(10)]
    return b


def test_samples_from_the_start_on_with_t_zero_at_the_start():
    rec = assemble(_buffer(), CellParams(), "r")
    assert rec.pose_t[0] == 0.0 and rec.profile_t[0] == 0.0
    assert np.allclose(np.diff(rec.pose_t), 0.02)
    assert rec.wrench_t is not None and rec.wrench_t.size == 10


def test_a_late_first_sample_keeps_the_state_at_rest_before_the_start():
    rec = assemble(_buffer(late_ns=300_000_000), CellParams(), "r")
    # the pose at rest before the start, re-stamped at the start, then the late ones
    assert rec.pose_t[0] == 0.0 and rec.pose_t[1] == pytest.approx(0.3)
    assert rec.profile_t[0] == 0.0 and rec.profile_t[1] == pytest.approx(0.3)


def test_what_cannot_be_a_record_is_refused_with_the_reason():
    with pytest.raises(RecordCellError, match="the process never started"):
        assemble(CellBuffer(), CellParams(), "r")
    with pytest.raises(RecordCellError, match="not at rest at the first set-point"):
        assemble(_buffer(late_ns=300_000_000, rest=False), CellParams(), "r")
    b = _buffer()
    b.profile = b.profile[:1]
    with pytest.raises(RecordCellError, match="a record needs a camera"):
        assemble(b, CellParams(), "r")


def test_the_buffer_takes_the_earliest_start_and_completes_when_the_run_is_over():
    from rheo_shaping.planning.states import AT_REST, MOVING
    from rheo_shaping.records.assembly import CellBuffer
    from rheo_shaping.units import NS
    b = CellBuffer()
    b.command(0, (0.0, 0.0))                       # unstamped: no start
    assert b.start_ns is None and b.recorded_time() == 0.0
    b.command(5 * NS, (0.05, 0.1))
    b.command(6 * NS, (0.06, 0.1))                 # later: not the start
    assert (b.start_ns, b.start_xz) == (5 * NS, (0.05, 0.1))
    b.plan(4 * NS)                                 # the plan's stamp: an earlier start
    assert b.start_ns == 4 * NS and b.start_xz == (0.05, 0.1)
    b.pose.append((4 * NS + 60 * NS, 0.05, 0.1))
    assert b.recorded_time() == 60.0
    b.state("waiting", MOVING)
    assert not b.complete(60.0, False, AT_REST)        # never ran
    assert b.complete(60.0, True, AT_REST)             # a fixed duration: recorded
    b.state("running", MOVING)
    assert not b.complete(60.0, False, AT_REST) and b.ran
    b.state("done", MOVING)
    assert b.complete(60.0, False, AT_REST) and not b.complete(61.0, False, AT_REST)
