"""A record as another tool reads it: the ``mcap`` and ``mcap-ros2-support`` packages
(Foxglove's reader, no rosbags and no ROS; its DecoderFactory, which the deprecated
``mcap_ros2.reader.read_ros2_messages`` wraps) decode every message of a record that
records.write_record wrote, and each is what was written; metadata.yaml says what
rosbag2 on Jazzy says (``ros_distro``, the offered QoS profiles)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import yaml

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import synthesize_record
from rheo_shaping.records.measurement import MeasurementParams
from rheo_shaping.records.qos import RECORDED_QOS
from rheo_shaping.records.bag import POSE, PROFILE, TYPES, WRENCH, write_record

START = 1_764_000_000.0     # a wall-clock start stamp [s]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    p = CellParams()
    cell = replace(p, movement=replace(p.movement, process_time=12.0))
    rec, _ = synthesize_record(cell, MeasurementParams(), seed=5, name="indep")
    assert rec.has_wrench and len(rec.profiles) > 5
    out = write_record(rec, tmp_path_factory.mktemp("rec") / "indep", start_stamp=START)
    return rec, out


def _ns(t: float) -> int:
    return int(round((START + t) * 1e9))


def test_every_message_decodes_to_what_was_written(written):
    rec, out = written
    (mcap_file,) = out.glob("*.mcap")
    got = {POSE: [], PROFILE: [], WRENCH: []}
    with open(mcap_file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            assert schema.name == TYPES[channel.topic]
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            assert message.log_time == stamp and msg.header.frame_id == "cake"
            got[channel.topic].append((stamp, msg))
    assert [len(got[t]) for t in (POSE, PROFILE, WRENCH)] == \
        [rec.pose_t.size, len(rec.profiles), rec.wrench_t.size]
    for (stamp, msg), t, (x, z) in zip(got[POSE], rec.pose_t, rec.pose_xz):
        p, q = msg.pose.position, msg.pose.orientation
        assert stamp == _ns(t) and (p.x, p.y, p.z) == (x, 0.0, z)
        assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    for (stamp, msg), t, pts in zip(got[PROFILE], rec.profile_t, rec.profiles):
        assert stamp == _ns(t)
        xyz = np.array([[q.position.x, q.position.y, q.position.z] for q in msg.poses])
        assert np.array_equal(xyz.reshape(-1, 3), np.c_[pts[:, 0], 0 * pts[:, 0], pts[:, 1]])
    for (stamp, msg), t, (fx, fz) in zip(got[WRENCH], rec.wrench_t, rec.wrench_xz):
        f, tq = msg.wrench.force, msg.wrench.torque
        assert stamp == _ns(t) and (f.x, f.y, f.z) == (fx, 0.0, fz)
        assert (tq.x, tq.y, tq.z) == (0.0, 0.0, 0.0)


def test_metadata_names_jazzy_and_the_offered_qos(written):
    rec, out = written
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy" and info["version"] == 9
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert set(topics) == set(TYPES)
    for name, t in topics.items():
        (offered,) = t["topic_metadata"]["offered_qos_profiles"]
        (spec,) = RECORDED_QOS[name]
        assert offered["history"] == spec.history == "keep_last"
        assert offered["depth"] == spec.depth == 100
        assert offered["reliability"] == "reliable" and offered["durability"] == "volatile"
        assert offered["deadline"] == {"sec": 0, "nsec": 0}
    # the copy of the metadata inside the MCAP file (what rosbag2 reads there) agrees
    (mcap_file,) = out.glob("*.mcap")
    with open(mcap_file, "rb") as f:
        (md,) = [m for m in make_reader(f).iter_metadata() if m.name == "rosbag2"]
    inner = yaml.safe_load(md.metadata["serialized_metadata"])
    assert inner["ros_distro"] == "jazzy"
    assert inner["topics_with_message_count"] == info["topics_with_message_count"]
