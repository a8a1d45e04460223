"""Recorded runs on disk: rosbag2 (MCAP) directories with ``scenario.yaml`` (docs/interfaces.md).

Read and written with the ``rosbags`` library (pure Python, no ROS install):

=========================  ===============================  ========
topic                      type                             required
=========================  ===============================  ========
``/tool/pose``             geometry_msgs/msg/PoseStamped    yes
``/sheet/measured_profile``  geometry_msgs/msg/PoseArray    yes
``/tool/wrench``           geometry_msgs/msg/WrenchStamped  no
=========================  ===============================  ========

A message's time is its header stamp; t = 0 is the earliest ``/tool/pose``
stamp, and all stamps of the three topics lie within ``MAX_RECORD_SECONDS`` of
each other (a stamp beyond is wrong: zero, or from another clock).
``scenario.yaml`` is the nominal cell in the project's params schema.
Synthetic stand-ins also hold ``truth.yaml`` (the cell with the effects that
made them): for benchmarks only, the diagnosis never reads it.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..params.config import ConfigError, dump_cell, load_cell
from ..params.cell import CellParams
from .qos import RECORDED_QOS, to_rosbags
from .record import Record
from ..units import NS

if TYPE_CHECKING:                      # rosbags is imported where a record is read or written
    from rosbags.rosbag2 import Writer

POSE, PROFILE, WRENCH = "/tool/pose", "/sheet/measured_profile", "/tool/wrench"
TYPES = {POSE: "geometry_msgs/msg/PoseStamped", PROFILE: "geometry_msgs/msg/PoseArray",
         WRENCH: "geometry_msgs/msg/WrenchStamped"}


#: The longest time [s] a record's stamps may span: one shaping run lasts minutes.
MAX_RECORD_SECONDS = 3600.0


class RecordError(ValueError):
    """A record that cannot be used; the message names the directory and what is wrong."""


def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def _header(ts, stamp_s: float):
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    ns = int(round(stamp_s * NS))
    return Header(stamp=Time(sec=ns // NS, nanosec=ns % NS), frame_id="cake")


def _pose(ts, x: float, z: float):
    P, Pt, Q = (ts.types[f"geometry_msgs/msg/{n}"] for n in ("Pose", "Point", "Quaternion"))
    return P(position=Pt(x=float(x), y=0.0, z=float(z)), orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0))


#: The ROS 2 distribution the records are written for (metadata.yaml ``ros_distro``).
ROS_DISTRO = "jazzy"


def _with_distro(metadata: str) -> str:
    """rosbags' metadata text with ``ros_distro: jazzy`` (rosbags writes its own name)."""
    import re
    text, n = re.subn(r"^(\s*ros_distro:) *\S+ *$", rf"\1 {ROS_DISTRO}", metadata,
                      flags=re.MULTILINE)
    if n != 1:
        raise RecordError(f"metadata: expected one ros_distro line, found {n}")
    return text


def _jazzy_writer() -> type[Writer]:
    """``rosbags``' Writer that names the distribution as rosbag2 on Jazzy does, in
    metadata.yaml and in the copy of it inside the MCAP file (its ``rosbag2`` record)."""
    from rosbags.rosbag2 import Writer

    class JazzyWriter(Writer):
        def close(self):
            storage = self.storage
            if storage is not None:
                close_storage = storage.close
                # rosbags has no hook for the metadata it writes into the MCAP file: this
                # writer's storage gets a close that rewrites it (a method replaced on purpose)
                storage.close = lambda version, metadata: (  # type: ignore[method-assign]
                    close_storage(version, _with_distro(metadata)))
            super().close()
            if storage is not None:
                tmp = self.metapath.with_suffix(".yaml.tmp")
                tmp.write_text(_with_distro(self.metapath.read_text("utf8")), "utf8")
                tmp.replace(self.metapath)

    return JazzyWriter


def is_record_dir(path: str | Path) -> bool:
    """Whether ``path`` is a folder this module wrote (the one kind ``force`` replaces)."""
    p = Path(path)
    return (p / "metadata.yaml").is_file() and (p / "scenario.yaml").is_file()


def write_record(record: Record, out_dir: str | Path, truth: CellParams | None = None,
                 start_stamp: float | None = None, force: bool = False) -> Path:
    """Write ``record`` as a rosbag2 MCAP directory ``out_dir`` with scenario.yaml (and
    truth.yaml).

    ``start_stamp`` [s] is the stamp of t = 0; None or 0: the wall-clock time now (whole
    seconds), as a real cell's record has (a zero stamp is a fault to the monitor).
    """
    import shutil
    import time

    if not start_stamp:
        start_stamp = float(int(time.time()))

    from rosbags.rosbag2 import StoragePlugin

    out = Path(out_dir)
    if out.exists():
        if not force:
            raise RecordError(f"{out} exists: not overwritten (use --force to replace it)")
        if not is_record_dir(out):
            raise RecordError(f"{out} exists and is not a record directory: not replaced")
        shutil.rmtree(out)
    if not out.parent.exists():
        raise RecordError(f"{out}: folder {out.parent} does not exist")
    ts = _typestore()
    PoseStamped, PoseArray = ts.types[TYPES[POSE]], ts.types[TYPES[PROFILE]]
    WrenchStamped, Wrench, Vector3 = (ts.types[f"geometry_msgs/msg/{n}"]
                                      for n in ("WrenchStamped", "Wrench", "Vector3"))
    messages = []   # (stamp_ns, connection key, message)
    for t, (x, z) in zip(record.pose_t, record.pose_xz):
        messages.append((t, POSE, PoseStamped(header=_header(
            ts, start_stamp + t), pose=_pose(ts, x, z))))
    for t, pts in zip(record.profile_t, record.profiles):
        messages.append((t, PROFILE, PoseArray(header=_header(ts, start_stamp + t),
                                               poses=[_pose(ts, x, z) for x, z in pts])))
    if record.has_wrench:
        # every maker of a Record gives the forces with the stamps
        assert record.wrench_t is not None and record.wrench_xz is not None
        for t, (fx, fz) in zip(record.wrench_t, record.wrench_xz):
            w = Wrench(force=Vector3(x=float(fx), y=0.0, z=float(fz)),
                       torque=Vector3(x=0.0, y=0.0, z=0.0))
            messages.append((t, WRENCH, WrenchStamped(
                header=_header(ts, start_stamp + t), wrench=w)))
    messages.sort(key=lambda m: m[0])
    with _jazzy_writer()(out, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {topic: writer.add_connection(
                     topic, TYPES[topic], typestore=ts,
                     offered_qos_profiles=[to_rosbags(q) for q in RECORDED_QOS[topic]])
                 for topic in TYPES if topic != WRENCH or record.has_wrench}
        for t, topic, msg in messages:
            stamp = int(round((start_stamp + t) * NS))
            writer.write(conns[topic], stamp, ts.serialize_cdr(msg, TYPES[topic]))
    (out / "scenario.yaml").write_text(
        "# The nominal cell of this run (rheo_shaping params "
        "schema).\n" + dump_cell(record.scenario))
    if truth is not None:
        (out / "truth.yaml").write_text(
            "# For benchmarks only: the cell with the effects that made this synthetic run.\n"
            "# The diagnosis never reads this file.\n" + dump_cell(truth))
    return out


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec / NS


def read_record(path: str | Path) -> Record:
    """Read a record directory; :class:`RecordError` names the directory and the fault."""
    from rosbags.rosbag2 import Reader

    p = Path(path)
    if not p.is_dir():
        raise RecordError(f"record {p}: not a directory")
    if not (p / "metadata.yaml").exists():
        raise RecordError(f"record {p}: no metadata.yaml (not a rosbag2 directory)")
    if not (p / "scenario.yaml").exists():
        raise RecordError(f"record {p}: no scenario.yaml (the nominal cell of the run)")
    try:
        scenario = load_cell(p / "scenario.yaml")
    except ConfigError as exc:
        raise RecordError(f"record {p}: {exc}") from None
    ts = _typestore()
    data: dict[str, list] = {POSE: [], PROFILE: [], WRENCH: []}
    try:
        with Reader(p) as reader:
            conns = [c for c in reader.connections if c.topic in TYPES]
            for c in conns:
                if c.msgtype != TYPES[c.topic]:
                    raise RecordError(f"record {p}: topic {c.topic} has type {c.msgtype}, "
                                      f"expected {TYPES[c.topic]}")
            for conn, _, raw in reader.messages(connections=conns):
                msg = ts.deserialize_cdr(raw, conn.msgtype)
                if conn.topic == POSE:
                    data[POSE].append((_stamp(msg), msg.pose.position.x, msg.pose.position.z))
                elif conn.topic == PROFILE:
                    pts = np.array([[q.position.x, q.position.z]
                                   for q in msg.poses], float).reshape(-1, 2)
                    data[PROFILE].append((_stamp(msg), pts))
                else:
                    f = msg.wrench.force
                    data[WRENCH].append((_stamp(msg), f.x, f.z))
    except RecordError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds for a broken bag
        raise RecordError(
            f"record {p}: cannot be read as a rosbag2 bag ({type(exc).__name__}: {exc})") from None
    for topic in (POSE, PROFILE):
        if len(data[topic]) < 2:
            raise RecordError(f"record {p}: topic {topic} ({TYPES[topic]}) is required and has "
                              f"{len(data[topic])} message(s); expected at least 2")
    return _assemble(scenario, data, p.name, p)


def _assemble(scenario: CellParams, data: dict, name: str, where) -> Record:
    pose = np.array(sorted(data[POSE]), float)
    t0 = pose[0, 0]
    frames = sorted(data[PROFILE], key=lambda f: f[0])
    for values, what in ((pose[:, 1:], "/tool/pose"),
                         (np.vstack([f[1] for f in frames] or [np.zeros((0, 2))]), PROFILE)):
        if not np.all(np.isfinite(values)):
            raise RecordError(f"record {where}: {what} holds non-finite positions")
    wrench_t = wrench = None
    if data[WRENCH]:
        w = np.array(sorted(data[WRENCH]), float)
        if not np.all(np.isfinite(w)):
            raise RecordError(f"record {where}: /tool/wrench holds non-finite forces")
        wrench_t, wrench = w[:, 0] - t0, w[:, 1:]
    pose_t, profile_t = pose[:, 0] - t0, np.array([f[0] for f in frames]) - t0
    _check_span(where, {POSE: pose_t, PROFILE: profile_t, WRENCH: wrench_t})
    return Record(scenario=scenario, pose_t=pose_t, pose_xz=pose[:, 1:],
                  profile_t=profile_t,
                  profiles=tuple(f[1] for f in frames), wrench_t=wrench_t, wrench_xz=wrench,
                  name=name, path=Path(where) if not isinstance(where, Path) else where)


def _check_span(where, stamps: dict) -> None:
    """Every stamp [s, from the first pose stamp] of ``stamps`` (topic: times or None)
    within ``MAX_RECORD_SECONDS`` of the others."""
    ends = {topic: (float(t.min()), float(t.max())) for topic, t in stamps.items()
            if t is not None}
    lo, hi = min(a for a, _ in ends.values()), max(b for _, b in ends.values())
    if hi - lo <= MAX_RECORD_SECONDS:      # a non-finite span is refused (NaN compares False)
        return
    topic, t = max(((k, v) for k, pair in ends.items() for v in pair), key=lambda kv: abs(kv[1]))
    raise RecordError(
        f"record {where}: its stamps span {hi - lo:.6g} s ({topic} has one {t:.6g} s from "
        f"the first /tool/pose stamp); expected at most {MAX_RECORD_SECONDS:g} s for one "
        f"run: a stamp is wrong (zero, or from another clock)")


def read_truth(path: str | Path) -> CellParams | None:
    """The true cell of a synthetic record (``truth.yaml``), or None. Benchmarks only."""
    p = Path(path) / "truth.yaml"
    return load_cell(p) if p.exists() else None
