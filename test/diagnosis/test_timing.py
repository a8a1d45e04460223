"""Whose clock a lag is on (:mod:`rheo_shaping.diagnosis.timing`): on the model's own
noise-free records, a camera that sees the sheet late by a known lag gives that lag back,
with and without a camera offset; a record whose profile does not lag gives none, and the
chain's load-cell lag is kept as the load cell's."""
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.diagnosis.baseline import CHAIN
from rheo_shaping_validation.benchmark import base_cell
from rheo_shaping.diagnosis.compare import RecordData
from rheo_shaping.diagnosis.evaluate import Task, run_task
from rheo_shaping.diagnosis.timing import (LAG_GRID_S, PROFILE_SHARE, driven_points, lag_check,
                                           profile_lag)
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams

LAG_S = 0.3
#: The grid's step is 0.05 s; the parabola through three points of a misfit that is
#: quadratic in the shift near its least (the sheet moves smoothly) lands within a fifth of it.
WITHIN_S = 0.01


@pytest.fixture(scope="module")
def record():
    ms = MeasurementParams(profile_noise=0.0, pose_noise=0.0, wrench_noise=0.0)
    rec, _ = synthesize_record(base_cell(15, 30.0), ms, seed=11)
    return rec


def _seen_late(rec, lag_s: float, offset_m=(0.0, 0.0)):
    """``rec`` as a camera sees it that shows the sheet of time t at t + ``lag_s``, shifted
    by ``offset_m``; frames past the pose's last stamp dropped."""
    keep = rec.profile_t + lag_s <= rec.pose_t[-1]
    frames = tuple(np.asarray(f) + np.asarray(offset_m) for f, k in zip(rec.profiles, keep) if k)
    return replace(rec, profile_t=rec.profile_t[keep] + lag_s, profiles=frames)


def _at_model(rec):
    d = RecordData.of(rec)
    return d, run_task(Task(d, rec.scenario, keep_run=True))


def _chain_u(force_lag_s: float) -> np.ndarray:
    u = np.zeros(len(CHAIN))
    k = [c.name for c in CHAIN].index("load_cell.lag")
    u[k] = force_lag_s / CHAIN[k].tolerance
    return u


def test_a_profile_seen_late_gives_its_lag_back_with_or_without_a_camera_offset(record):
    for offset in ((0.0, 0.0), (4e-4, -3e-4)):
        d, o = _at_model(_seen_late(record, LAG_S, offset))
        assert o.ok
        assert profile_lag([d], [o]) == pytest.approx(LAG_S, abs=WITHIN_S)
    d, o = _at_model(record)
    assert abs(profile_lag([d], [o])) < WITHIN_S
    assert LAG_GRID_S.min() < 0 < LAG_S < LAG_GRID_S.max()


def test_the_lag_is_read_on_the_frames_the_tool_drives_alone(record):
    """Frames before the tool touches and after it leaves (a laid sheet settling at its own
    pace in a real cell) do not enter: moved by 2 mm, they leave the lag as it was, while
    over every frame they move it."""
    d, o = _at_model(record)
    driven = driven_points(d, o)
    assert driven.any() and not driven.all()
    frames = set(np.unique(d.point_frame[~driven]))
    for lag_s in (0.0, LAG_S):
        late = _seen_late(record, lag_s)
        keep = record.profile_t + lag_s <= record.pose_t[-1]
        idx = np.flatnonzero(keep)
        moved = tuple(np.asarray(f) + (np.array([0.0, 2e-3]) if i in frames else 0.0)
                      for i, f in zip(idx, late.profiles))
        dl, ol = _at_model(replace(late, profiles=moved))
        assert profile_lag([dl], [ol]) == pytest.approx(lag_s, abs=WITHIN_S)
        assert abs(profile_lag([dl], [ol], driven=False) - lag_s) > 2 * WITHIN_S


def test_a_lag_the_camera_sees_too_is_the_tool_s_and_one_it_does_not_is_the_load_cell_s(record):
    d, o = _at_model(_seen_late(record, LAG_S))
    late = lag_check([d], [o], _chain_u(LAG_S))
    assert late["tool_lags"] and late["force_lag_s"] == pytest.approx(LAG_S)
    d, o = _at_model(record)
    own = lag_check([d], [o], _chain_u(LAG_S))
    assert not own["tool_lags"]
    assert abs(own["profile_lag_s"]) < PROFILE_SHARE * LAG_S
    # the rule's edge: a profile lag just under and just over PROFILE_SHARE of the force's
    d, o = _at_model(_seen_late(record, 0.1))
    assert lag_check([d], [o], _chain_u(0.1 / (PROFILE_SHARE * 0.85)))["tool_lags"] is False
    assert lag_check([d], [o], _chain_u(0.1 / (PROFILE_SHARE * 1.15)))["tool_lags"] is True
