"""Recorded runs: rosbag2 MCAP directories written and read with rosbags, the measurement
model, the CSV importer and the `record` / `import-csv` commands (real files in tmp_path)."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.cli import main
from rheo_shaping.params.config import dump_cell
from rheo_shaping.records.csv_import import import_csv
from rheo_shaping.sheet.effects import EFFECTS
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams, nodes_at, resample_polyline
from rheo_shaping.params.cell import CellParams
from rheo_shaping.records.bag import RecordError, read_record, read_truth, write_record


@pytest.fixture(scope="module")
def short_cell():
    p = CellParams()
    return replace(p, movement=replace(p.movement, process_time=30.0))


@pytest.fixture(scope="module")
def synthetic(short_cell):
    truth = EFFECTS["mass_error"].apply(short_cell, (0.2,))
    return synthesize_record(truth, MeasurementParams(), seed=3, name="r"), truth


def test_round_trip_with_wall_clock_stamps(tmp_path, synthetic):
    (rec, _), truth = synthetic
    out = write_record(rec, tmp_path / "run", truth=truth, start_stamp=1.7e9)
    back = read_record(out)
    assert back.pose_t[0] == 0.0                                  # t = 0 at the first pose stamp
    assert np.max(np.abs(back.pose_t - rec.pose_t)) < 1e-6       # ns stamps around 1.7e9 s
    assert np.array_equal(back.pose_xz, rec.pose_xz)
    assert len(back.profiles) == len(rec.profiles)
    assert all(np.array_equal(a, b) for a, b in zip(back.profiles, rec.profiles))
    assert np.array_equal(back.wrench_xz, rec.wrench_xz)
    assert back.scenario == rec.scenario == replace(truth, effects=CellParams().effects)
    assert read_truth(out) == truth
    assert (out / "metadata.yaml").exists() and list(out.glob("*.mcap"))


def test_profile_points_lie_on_the_sheet_and_are_spaced_along_it(short_cell):
    ms = MeasurementParams(profile_noise=0.0, point_dropout=0.0, frame_dropout=0.0, pose_noise=0.0)
    rec, run = synthesize_record(short_cell, ms, seed=1)
    for k in (0, len(rec.profiles) // 2, -1):
        pts = rec.profiles[k]
        line = nodes_at(run, rec.profile_t[k])
        seg = np.diff(line, axis=0)
        # each point lies on the polyline (distance to the nearest segment)
        rel = pts[:, None, :] - line[None, :-1, :]
        s = np.clip(np.einsum("psk,sk->ps", rel, seg) / np.einsum("sk,sk->s", seg, seg), 0, 1)
        dist = np.linalg.norm(rel - s[..., None] * seg, axis=2)
        assert np.max(np.min(dist, axis=1)) < 1e-12
        # consecutive points are one spacing apart along the sheet's arc (not its chords)
        seg_len = np.linalg.norm(seg, axis=1)
        j = np.argmin(dist, axis=1)
        arc = np.r_[0.0, np.cumsum(seg_len)][j] + s[np.arange(len(j)), j] * seg_len[j]
        assert np.allclose(np.diff(arc), ms.profile_spacing, rtol=1e-9, atol=1e-12)
        chord = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        assert np.max(chord) <= ms.profile_spacing + 1e-12
    assert not np.any(
        np.all(np.isclose(rec.profiles[0][:, None, :], run.x[0][None, :, :]), axis=2))


def test_resample_polyline_spacing_exact():
    pts = resample_polyline(np.array([[0.0, 0.0], [0.01, 0.0], [0.01, 0.01]]), 3e-3, 1e-3)
    assert np.allclose(pts[:4], [[1e-3, 0], [4e-3, 0], [7e-3, 0], [1e-2, 0]], atol=1e-15)
    assert np.allclose(pts[4:], [[1e-2, 3e-3], [1e-2, 6e-3], [1e-2, 9e-3]], atol=1e-15)


def test_dropouts_and_noise_match_the_measurement_model(short_cell):
    ms = MeasurementParams(frame_dropout=0.3, point_dropout=0.2, profile_rate=10.0)
    rec, run = synthesize_record(short_cell, ms, seed=7)
    frames_expected = int(short_cell.movement.process_time * 10) + 1
    kept = len(rec.profiles) / frames_expected
    sd = np.sqrt(0.3 * 0.7 / frames_expected)
    assert abs(kept - 0.7) < 4 * sd
    full = int(np.median([len(f) for f in rec.profiles]) / 0.8)
    assert 0.74 < np.median([len(f) for f in rec.profiles]) / full <= 0.86
    assert rec.pose_t[1] - rec.pose_t[0] == pytest.approx(1 / 50)
    ms0 = replace(ms, pose_noise=0.0)
    rec0, _ = synthesize_record(short_cell, ms0, seed=7)
    assert np.std(rec.pose_xz - rec0.pose_xz) == pytest.approx(5e-5, rel=0.05)


def test_read_errors_name_the_record(tmp_path, synthetic):
    (rec, _), _ = synthetic
    with pytest.raises(RecordError, match="not a directory"):
        read_record(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(RecordError, match=r"empty: no metadata.yaml"):
        read_record(tmp_path / "empty")
    # a bag without the profile topic
    no_profile = replace(rec, profile_t=rec.profile_t[:0], profiles=())
    out = write_record(no_profile, tmp_path / "noprof")
    with pytest.raises(RecordError, match=r"/sheet/measured_profile .* is required"):
        read_record(out)
    # a broken scenario.yaml
    out = write_record(rec, tmp_path / "badscen")
    (out / "scenario.yaml").write_text("/**:\n  ros__parameters:\n    material: {k1: -3.0}\n")
    with pytest.raises(RecordError, match=r"badscen.*material.k1"):
        read_record(out)
    # refuses to overwrite
    with pytest.raises(RecordError, match="exists: not overwritten"):
        write_record(rec, out)


@pytest.mark.parametrize("topic", ["/tool/pose", "/sheet/measured_profile", "/tool/wrench"])
def test_a_stamp_far_from_the_run_is_named(tmp_path, synthetic, topic):
    """One stamp 2**31 - 1 s (the largest) off, as a wrong clock gives: refused by name, not
    a diagnosis that plans a 68-year tool path (80 GiB; found by fuzz_inputs, seed 24)."""
    (rec, _), _ = synthetic
    field = {"/tool/pose": "pose_t", "/sheet/measured_profile": "profile_t",
             "/tool/wrench": "wrench_t"}[topic]
    t = getattr(rec, field).copy()
    t[-1] = 2.0 ** 31 - 1 - 1.7e9
    out = write_record(replace(rec, **{field: t}), tmp_path / "far", start_stamp=1.7e9)
    with pytest.raises(RecordError, match=rf"far: its stamps span .* \({topic} has one "
                                          rf".*expected at most 3600 s"):
        read_record(out)
    t[-1] = rec.pose_t[-1] + 3000.0                   # within an hour: a valid (long) record
    ok = write_record(replace(rec, **{field: t}), tmp_path / "near", start_stamp=1.7e9)
    assert read_record(ok).duration == pytest.approx(t[-1], abs=1e-6)


def write_csvs(tmp_path, rec):
    (tmp_path / "pose.csv").write_text("t,x,z\n" + "\n".join(
        f"{float(t) + 100.0!r},{float(x)!r},{float(z)!r}" for t,
        (x, z) in zip(rec.pose_t,
                      rec.pose_xz)) + "\n")
    rows = [f"{float(t) + 100.0!r},{float(x)!r},{float(z)!r}" for t,
            f in zip(rec.profile_t, rec.profiles) for x, z in f]
    (tmp_path / "profile.csv").write_text("t,x,z\n" + "\n".join(rows) + "\n")
    (tmp_path / "wrench.csv").write_text("t,fx,fz\n" + "\n".join(
        f"{float(t) + 100.0!r},{float(x)!r},{float(z)!r}" for t,
        (x,
         z) in zip(rec.wrench_t,
                   rec.wrench_xz)) + "\n")
    (tmp_path / "scenario.yaml").write_text(dump_cell(rec.scenario))


def test_csv_import_equals_the_record(tmp_path, synthetic):
    (rec, _), _ = synthetic
    write_csvs(tmp_path, rec)
    back = import_csv(tmp_path / "scenario.yaml", tmp_path / "pose.csv", tmp_path / "profile.csv",
                      tmp_path / "wrench.csv")
    assert np.allclose(back.pose_t, rec.pose_t, atol=1e-9)
    assert len(back.profiles) == len(rec.profiles)
    assert all(np.array_equal(a, b) for a, b in zip(back.profiles, rec.profiles))
    assert np.array_equal(back.wrench_xz, rec.wrench_xz)
    # and through the command, into a record the diagnosis reads
    assert main(["import-csv", "--scenario", str(tmp_path / "scenario.yaml"), "--pose",
                 str(tmp_path / "pose.csv"),
                 "--profile", str(tmp_path / "profile.csv"), "--out",
                 str(tmp_path / "imported")]) == 0
    assert len(read_record(tmp_path / "imported").profiles) == len(rec.profiles)


@pytest.mark.parametrize("content,message", [
    ("t,x\n0,1\n", r"line 1: missing column 'z'"),
    ("t,x,z\n0,1,2\n0.1,abc,2\n", r"line 3, column 'x': 'abc' is not a number"),
    ("t,x,z\n0,1,2\n0.1,nan,2\n", r"line 3, column 'x': 'nan' is not a finite number"),
    ("t,x,z\n0.2,1,2\n0.1,1,2\n", r"line 3, column 't': times must not decrease"),
])
def test_malformed_csv_is_named_and_nothing_is_written(tmp_path, synthetic, capsys, content,
                                                       message):
    (rec, _), _ = synthetic
    write_csvs(tmp_path, rec)
    (tmp_path / "pose.csv").write_text(content)
    code = main(["import-csv", "--scenario", str(tmp_path / "scenario.yaml"), "--pose",
                 str(tmp_path / "pose.csv"),
                 "--profile", str(tmp_path / "profile.csv"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "pose.csv" in err and "Traceback" not in err
    import re
    assert re.search(message, err), err
    assert not (tmp_path / "out").exists()


def test_record_command_with_an_effect(tmp_path, capsys):
    params = tmp_path / "cell.yaml"
    params.write_text("/**:\n  ros__parameters:\n    movement: {process_time: 20.0}\n"
                      "    effects: {kelvin_c1: 800.0}\n")
    out = tmp_path / "rec"
    assert main(["record", "--params", str(params), "--out",
                str(out), "--seed", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["effects"] == ["kelvin_c1"] and summary["profile_frames"] > 30
    rec = read_record(out)
    assert rec.scenario.effects == CellParams().effects          # the truth is not in the scenario
    assert read_truth(out).effects.kelvin_c1 == 800.0
    # refuses to overwrite, one-line error
    assert main(["record", "--params", str(params), "--out", str(out)]) == 2
    assert "exists: not overwritten" in capsys.readouterr().err
