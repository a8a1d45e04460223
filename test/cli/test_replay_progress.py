"""``replay``'s progress: a bar of the recorded seconds replayed with an ETA, drawn only for a
readable record.  The replay itself needs ROS (test/nodes/test_record_cell.py runs it); the
bar does not."""
from __future__ import annotations

import time

from rheo_shaping.cli.replay import _Progress, _span_s


def _last(err: str) -> str:
    return err.replace("\r", "\n").strip().splitlines()[-1]


def test_the_bar_counts_recorded_seconds_from_the_first_message(capsys):
    bar = _Progress(span_s=20.0, rate=10.0, quiet=False)
    time.sleep(0.5)
    assert bar.bar.n == 0, "nothing counts before the replay's first message"
    bar.say("replay: run-07 from stamp 12.000 s at x10")
    time.sleep(1.0)
    n = bar.bar.n
    assert 5.0 <= n <= 19.98, n                  # ~1 s of wall clock at x10, never the end
    bar.close(finished=True)
    err = capsys.readouterr().err
    assert "replay: run-07 from stamp" in err
    assert "20.0/20.0 recorded s" in _last(err)
    assert "<" in _last(err)                     # elapsed<remaining: the ETA


def test_quiet_prints_nothing(capsys):
    bar = _Progress(span_s=5.0, rate=1.0, quiet=True)
    bar.say("replay: x")
    bar.close(finished=False)
    assert capsys.readouterr().err == ""


def test_span_of_a_record_and_of_a_broken_one(tmp_path):
    import numpy as np
    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.records.record import Record
    from rheo_shaping.records.bag import write_record
    rec = Record(scenario=CellParams(), pose_t=np.array([0.0, 1.0, 2.5]),
                 pose_xz=np.zeros((3, 2)), profile_t=np.array([0.0, 2.0]),
                 profiles=(np.zeros((2, 2)), np.zeros((2, 2))))
    out = write_record(rec, tmp_path / "r", start_stamp=1.7e9)
    assert abs(_span_s(out) - 2.5) < 1e-6            # rosbags counts last - first + 1 ns
    assert _span_s(tmp_path / "missing") == 0.0   # the replay then says what is wrong


def test_a_bad_record_is_said_before_any_bar(capsys, tmp_path):
    """The error alone, on one line: no progress bar drawn first (and no ROS needed)."""
    from rheo_shaping.cli import main
    missing, empty = tmp_path / "missing", tmp_path / "empty"
    empty.mkdir()
    for record, why in ((missing, "not a directory"),
                        (empty, "no metadata.yaml (not a rosbag2 directory)")):
        assert main(["replay", str(record)]) == 2
        err = capsys.readouterr().err
        assert err == f"rheo-shaping replay: error: record {record}: {why}\n"
