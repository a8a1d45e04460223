"""The gap watch's core (rheo_shaping.gapwatch) against closed forms and measured behaviour.

* A record the model makes of itself (the measurement model's Gaussian noise) has residuals
  at the noise: the online noise estimates recover the measurement model's std, the RMS in
  noise units is 1 within the replay error, and the state stays OK.
* A load cell with a constant bias (bx, bz) on the model's own record: the systematic force
  residual is sqrt((bx^2 + bz^2) / 2) per axis, exactly (closed form).
* A tool offset (the `tool_offset` effect): the force residual is the model's own force change
  of that offset, F(offset) - F(nominal), within the noise's share.
* Rogue samples (NaN, stamps that go back or jump, malformed frames) are refused with a reason
  and never raise.
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rheo_shaping.gapwatch.feed import watch_record
from rheo_shaping.gapwatch.floor import DEFAULT_FLOOR, ResidualFloor, ResidualFloorError
from rheo_shaping.gapwatch.residuals import signed_distance
from rheo_shaping.gapwatch.watch import GapWatch
from rheo_shaping.params.config import load_cell
from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams
from rheo_shaping.records.bag import read_record, write_record
from rheo_shaping.sheet.effects import EFFECTS
from rheo_shaping.sheet.simulation import run_scenario

CELL_FILE = Path(__file__).resolve().parents[2] / "config" / "cell.yaml"
MS = MeasurementParams()


@pytest.fixture(scope="module")
def cell():
    return load_cell(CELL_FILE)


@pytest.fixture(scope="module")
def own(cell):
    """The model's own record (default measurement model) and the watch fed with it."""
    rec, run = synthesize_record(cell, MS, seed=11)
    return rec, run, watch_record(rec)


def test_signed_distance_is_the_normal_distance_with_the_left_normal_positive():
    line = np.array([[0.0, 1.0], [0.0, 0.0], [1.0, 0.0]])      # down the wall, along the floor
    pts = np.array([[0.2, 0.5], [-0.1, 0.5], [0.5, -0.3], [0.5, 0.25]])
    d = signed_distance(pts, line)
    # going down (0, -1) the left normal is +x; going along +x it is +z
    assert d == pytest.approx([0.2, -0.1, -0.3, 0.25])


def test_the_models_own_record_is_at_the_noise(own):
    rec, run, gw = own
    r = gw.residuals()
    # the online noise estimates recover the measurement model's std (0.3 mm, 0.01 N)
    assert r["noise"]["profile_m"] == pytest.approx(MS.profile_noise, rel=0.05)
    assert r["noise"]["force_N"] == pytest.approx(MS.wrench_noise, rel=0.05)
    # the run's RMS in noise units: 1 plus the replay error of the smoothed pose
    assert r["run"]["profile_m"]["z"] == pytest.approx(1.0, abs=0.1)
    assert r["run"]["force_N"]["z"] == pytest.approx(1.0, abs=0.1)
    assert gw.level == "OK" and gw.first_warn is None
    assert not gw.refused
    # the model ran to the record's end and judged every frame
    assert r["model_time_s"] == pytest.approx(rec.duration, abs=0.25)
    assert r["run"]["profile_m"]["n"] == sum(len(f) for f in rec.profiles)
    # every phase of movement 4 was seen
    assert set(r["phases"]) == {"approach", "forced deformation", "dwell", "release", "settle"}


def test_a_load_cell_bias_gives_its_closed_form_force_residual(own):
    rec, run, _ = own
    b = np.array([0.03, -0.04])                     # N
    gw = watch_record(replace(rec, wrench_xz=rec.wrench_xz + b))
    f = gw.residuals()["run"]["force_N"]
    s = gw.force_noise
    want = math.sqrt(float(b @ b) / 2.0)            # per-axis RMS of a constant bias
    # the systematic part is sqrt(mean r^2 - s^2): the bias plus the replay error (the own
    # record's systematic force residual, measured above: < 0.1 noise units)
    own_sys = math.sqrt(max(watch_record(rec).residuals()["run"]["force_N"]["rms"] ** 2
                            - s ** 2, 0.0))
    assert f["systematic"] == pytest.approx(math.hypot(want, own_sys), rel=0.03)
    assert gw.first_warn is not None and gw.first_warn < 20.0


def test_a_tool_offset_gives_the_models_own_force_change(cell):
    eff = EFFECTS["tool_offset"]
    truth = eff.apply(cell, (1.5e-3, -1.0e-3))
    rec, true_run = synthesize_record(truth, MS, seed=5)
    gw = watch_record(rec, model=cell)
    nominal = run_scenario(cell, movement_plan(cell))
    # expected: measured - model = F(offset) - F(nominal) at the wrench stamps, plus noise
    dF = np.c_[[np.interp(rec.wrench_t, true_run.t, true_run.tool_force[:, k])
                - np.interp(rec.wrench_t, nominal.t, nominal.tool_force[:, k]) for k in (0, 1)]].T
    want = math.sqrt(float(np.mean(dF ** 2)))
    got = gw.residuals()["run"]["force_N"]["systematic"]
    assert got == pytest.approx(want, rel=0.05)
    assert want > 5 * MS.wrench_noise              # the case is far above the noise
    assert gw.first_warn is not None and gw.level in ("WARN", "ERROR")


def test_rogue_samples_are_refused_with_a_reason(cell):
    gw = GapWatch(cell, ResidualFloor.load(), GapWatchNodeParams())
    gw.start(100.0)
    assert gw.pose(100.0, 0.03, 0.07) is None
    assert gw.pose(100.02, math.nan, 0.07) == "pose: non-finite position"
    assert gw.pose(99.0, 0.03, 0.07) == "pose: stamp before the process start"
    assert gw.pose(100.0, 0.03, 0.07) == "pose: stamp not after the previous one"
    assert gw.pose(3600.0, 0.03, 0.07).startswith("pose: stamp more than max_stamp_jump")
    assert gw.pose(math.inf, 0.03, 0.07) == "pose: non-finite stamp"
    assert gw.profile(100.01, [[0.0, 0.1], [0.0, 0.05]]).startswith("profile: fewer than 3")
    assert gw.profile(100.01, np.zeros((6000, 2))).startswith("profile: fewer than 3 or more")
    assert gw.profile(100.01, [[0, 0.1], [0, np.nan], [0, 0]]) == "profile: non-finite point"
    assert gw.profile(100.01, "garbage") == "profile: not a list of (x, z) points"
    assert gw.wrench(100.01, np.nan, 0.0) == "wrench: non-finite force"
    assert sum(gw.refused.values()) == 10
    assert gw.update() == [] and gw.level == "STALE"


def test_the_run_so_far_is_a_record_the_diagnosis_reads(own, tmp_path):
    rec, _, gw = own
    out = gw.record()
    write_record(out, tmp_path / "w")
    back = read_record(tmp_path / "w")
    assert back.pose_t.size == rec.pose_t.size
    assert len(back.profiles) == len(rec.profiles)
    assert np.allclose(back.wrench_xz, rec.wrench_xz)
    assert back.scenario == rec.scenario


def test_the_shipped_floor_loads_and_bad_floors_are_one_line_errors(tmp_path):
    fl = ResidualFloor.load()
    assert fl.runs >= 1 and fl.profile_window_z >= 1.0
    assert ResidualFloor.load(DEFAULT_FLOOR) == fl
    p = tmp_path / "f.json"
    p.write_text("{")
    with pytest.raises(ResidualFloorError, match="not JSON"):
        ResidualFloor.load(p)
    p.write_text(json.dumps({"profile_window_z": 0.5, "force_window_z": 1.2,
                             "profile_run_z": 1.1, "force_run_z": 1.1, "window_s": 10.0}))
    with pytest.raises(ResidualFloorError, match=r"'profile_window_z' = 0.5 is invalid: "
                                                 r"expected a finite number >= 1"):
        ResidualFloor.load(p)
    p.write_text(json.dumps({"profile_window_z": 1.5}))
    with pytest.raises(ResidualFloorError, match="field 'force_run_z' missing"):
        ResidualFloor.load(p)
    with pytest.raises(ResidualFloorError, match="cannot read it"):
        ResidualFloor.load(tmp_path / "missing.json")


def test_a_stream_that_resumes_after_a_gap_is_taken_up_and_the_run_no_longer_judged(own):
    rec, _, _ = own
    from rheo_shaping.gapwatch.feed import watch_record as feed
    # poses, frames and forces from 40 s to 75 s lost (a stalled link): 35 s, more than
    # max_stamp_jump (10 s) and than 3 of them
    keep = lambda t: (t < 40.0) | (t > 75.0)                       # noqa: E731
    kf = keep(rec.profile_t)
    cut = replace(rec, pose_t=rec.pose_t[keep(rec.pose_t)],
                  pose_xz=rec.pose_xz[keep(rec.pose_t)],
                  wrench_t=rec.wrench_t[keep(rec.wrench_t)],
                  wrench_xz=rec.wrench_xz[keep(rec.wrench_t)], profile_t=rec.profile_t[kf],
                  profiles=tuple(f for f, k in zip(rec.profiles, kf) if k))
    gw = feed(cut)
    r = gw.residuals()
    assert gw.refused["pose: the stream resumed after a gap (bridged)"] == 1
    assert gw.refused["pose: stamp more than max_stamp_jump after the newest pose"] == 9
    assert r["model_time_s"] == pytest.approx(rec.duration, abs=0.25)   # it went on
    assert gw.level == "STALE" and "lost from 40.0 s to 75.0" in gw.reason
    assert gw.first_warn is None


def test_a_short_gap_is_bridged_and_the_run_judged_on(own):
    rec, _, _ = own
    from rheo_shaping.gapwatch.feed import watch_record as feed
    keep = lambda t: (t < 40.0) | (t > 52.0)                       # noqa: E731  12 s lost
    kf = keep(rec.profile_t)
    cut = replace(rec, pose_t=rec.pose_t[keep(rec.pose_t)],
                  pose_xz=rec.pose_xz[keep(rec.pose_t)],
                  wrench_t=rec.wrench_t[keep(rec.wrench_t)],
                  wrench_xz=rec.wrench_xz[keep(rec.wrench_t)], profile_t=rec.profile_t[kf],
                  profiles=tuple(f for f, k in zip(rec.profiles, kf) if k))
    gw = feed(cut)
    assert gw.refused["pose: the stream resumed after a gap (bridged)"] == 1
    assert gw.level == "OK" and gw.first_warn is None       # a straight move, bridged


def test_the_diagnosis_at_warn_holds_the_model_cell_and_names_a_mass_error():
    """The watch's diagnosis (the node's worker task on the run up to the first WARN) holds
    the model cell's sheet knobs (``diagnosis_baseline: held``): a mass 27.5 % off is named
    ``mass_error`` (a calibrated baseline took it as k1, c2 and the mass at its bound and
    said ``none``, docs/gapwatch.md)."""
    from rheo_shaping_validation.gapwatch_campaign import Case, default_shared, run_case
    cell = load_cell(CELL_FILE)
    out = run_case(default_shared(cell), Case("mass_error", 1, diagnose=True))
    (true,) = out["values"]
    assert abs(true) == pytest.approx(0.275)
    assert out["first_warn"] is not None and out["first_warn"] < 20.0
    d = out["diagnosis"]
    assert not d["error"] and d["verdict"] == "mass_error", d
    (fraction,) = d["parameters"]["mass_error"]
    assert fraction == pytest.approx(true, abs=0.05)
