"""Fixtures: real Freiburg 079 maps (``tests/data``) and logs built from them with the libraries' own writers.

Logs are written with rosbags (ROS 1 bag, ROS 2 db3 / mcap folders) and the ``mcap`` package (bare MCAP,
ros2 and ros1 profiles), never with ``rose_logs.writer``, so the reader is tested against independent
output. Messages are serialised with rosbags typestores.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from real_data import FR079_DIR, repo_data
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

import rose

START_NS = 1_700_000_000_000_000_000
# Bounding box of the explored building in map15, a few cells of margin: 326 x 895 cells.
CROP = (slice(205, 531), slice(59, 954))

# (name, rosbags/mcap format, serialisation)
FORMATS = {
    "ros1": ("ros1", "ros1"),
    "ros1-bz2": ("ros1", "ros1"),
    "db3": ("db3", "cdr"),
    "mcap-dir": ("mcap-dir", "cdr"),
    "mcap-ros2": ("mcap", "cdr"),
    "mcap-ros1": ("mcap", "ros1"),
}
UPDATE_MSGDEF = (
    "std_msgs/Header header\nint32 x\nint32 y\nuint32 width\nuint32 height\nint8[] data\n"
)


def _qos_latched() -> Qos:
    zero = QosTime(sec=0, nsec=0)
    return Qos(
        QosHistory.KEEP_LAST,
        1,
        QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL,
        zero,
        zero,
        QosLiveliness.AUTOMATIC,
        zero,
        False,
    )


def _qos_yaml(profiles: list[Qos]) -> str:
    """QoS as rosbag2 writes it into MCAP channel metadata (YAML list of v9 dicts)."""
    import yaml
    from rosbags.rosbag2.metadata import dump_qos_v9

    return yaml.safe_dump(dump_qos_v9(profiles), default_flow_style=False).strip()


def load_crop(name: str) -> npt.NDArray[np.int8]:
    """``map<N>`` of the fr079 exploration, cropped to the building (326 x 895 cells)."""
    return np.ascontiguousarray(rose.load_map(repo_data(f"{FR079_DIR}/{name}.yaml")).grid[CROP])


@pytest.fixture(scope="session")
def fr079() -> list[npt.NDArray[np.int8]]:
    """Three growing real snapshots (map5, map10, map15), cropped."""
    return [load_crop(n) for n in ("map5", "map10", "map15")]


@pytest.fixture(scope="session")
def broken_grid(fr079: list[npt.NDArray[np.int8]]) -> npt.NDArray[np.int8]:
    """map15's known area with a quarter of its obstacle cells scattered at random (structure lost).

    W is about 0.5-0.6 here, above the paper's failure level 0.4; map5..map15 score about 0.15.
    """
    grid = fr079[-1]
    rng = np.random.default_rng(0)
    broken = np.where(grid >= 0, 0, -1).astype(np.int8)
    count = int(np.count_nonzero(grid >= 65)) // 4
    broken.ravel()[rng.choice(grid.size, count, replace=False)] = 100
    return broken


def typestore(serialization: str) -> Any:
    store = get_typestore(Stores.ROS1_NOETIC if serialization == "ros1" else Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(UPDATE_MSGDEF, "map_msgs/msg/OccupancyGridUpdate"))
    return store


@dataclass
class MapMsg:
    """A map (or update, with ``xy``) to put in a test log at ``t_ns``."""

    t_ns: int
    grid: npt.NDArray[np.int8]
    resolution_m: float = 0.05
    origin_xy_m: tuple[float, float] = (-100.0, -100.0)
    topic: str = "/map"
    xy: tuple[int, int] | None = None
    bad_length: bool = False
    yaw_rad: float = 0.0
    orientation_xyzw: tuple[float, float, float, float] | None = None  # instead of the yaw


@dataclass
class BuiltLog:
    path: Path
    fmt: str
    serialization: str
    maps: list[MapMsg] = field(default_factory=list)


def _serialize(store: Any, serialization: str, msg: Any, msgtype: str) -> bytes:
    if serialization == "ros1":
        return bytes(store.serialize_ros1(msg, msgtype))
    return bytes(store.serialize_cdr(msg, msgtype))


def _map_message(store: Any, serialization: str, m: MapMsg, seq: int) -> tuple[str, bytes]:
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](
        sec=m.t_ns // 1_000_000_000, nanosec=m.t_ns % 1_000_000_000
    )
    header_kw: dict[str, Any] = {"stamp": stamp, "frame_id": "map"}
    if serialization == "ros1":
        header_kw["seq"] = seq
    header = t["std_msgs/msg/Header"](**header_kw)
    h, w = m.grid.shape
    data = m.grid.ravel()
    if m.bad_length:
        data = data[:-7]
    if m.xy is not None:
        msgtype = "map_msgs/msg/OccupancyGridUpdate"
        msg = t[msgtype](header=header, x=m.xy[0], y=m.xy[1], width=w, height=h, data=data)
        return msgtype, _serialize(store, serialization, msg, msgtype)
    msgtype = "nav_msgs/msg/OccupancyGrid"
    qx, qy, qz, qw = m.orientation_xyzw or (
        0.0,
        0.0,
        math.sin(m.yaw_rad / 2),
        math.cos(m.yaw_rad / 2),
    )
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=m.origin_xy_m[0], y=m.origin_xy_m[1], z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
    )
    info = t["nav_msgs/msg/MapMetaData"](
        map_load_time=stamp, resolution=m.resolution_m, width=w, height=h, origin=pose
    )
    msg = t[msgtype](header=header, info=info, data=data)
    return msgtype, _serialize(store, serialization, msg, msgtype)


def _scan_message(store: Any, serialization: str, t_ns: int, seq: int) -> bytes:
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](
        sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000
    )
    header_kw: dict[str, Any] = {"stamp": stamp, "frame_id": "laser"}
    if serialization == "ros1":
        header_kw["seq"] = seq
    rng = np.random.default_rng(seq)
    msg = t["sensor_msgs/msg/LaserScan"](
        header=t["std_msgs/msg/Header"](**header_kw),
        angle_min=-1.57,
        angle_max=1.57,
        angle_increment=3.14 / 180,
        time_increment=0.0,
        scan_time=0.1,
        range_min=0.1,
        range_max=30.0,
        ranges=rng.uniform(0.5, 10.0, 181).astype(np.float32),
        intensities=np.zeros(0, dtype=np.float32),
    )
    return _serialize(store, serialization, msg, "sensor_msgs/msg/LaserScan")


def build_log(
    path: Path,
    kind: str,
    maps: Sequence[MapMsg],
    *,
    scans_per_map: int = 3,
    small_topics: int = 0,
) -> BuiltLog:
    """Write a log of ``kind`` (a key of ``FORMATS``) with ``maps`` and LaserScan traffic on ``/scan``,
    and ``small_topics`` topics of small std_msgs messages (a robot's sensors and diagnostics: Int32,
    String in turn), a message on each after every map."""
    fmt, serialization = FORMATS[kind]
    store = typestore(serialization)
    records: list[tuple[int, str, str, bytes]] = []  # (t, topic, msgtype, data)
    for seq, m in enumerate(maps):
        for i in range(small_topics):
            msgtype = ("std_msgs/msg/Int32", "std_msgs/msg/String")[i % 2]
            msg = store.types[msgtype](seq + i if i % 2 == 0 else f"ok {seq}")
            data = _serialize(store, serialization, msg, msgtype)
            records.append((m.t_ns + 1000 * (i + 1), f"/robot/sensor_{i:04d}", msgtype, data))
    for seq, m in enumerate(maps, start=1):
        msgtype, data = _map_message(store, serialization, m, seq)
        records.append((m.t_ns, m.topic, msgtype, data))
        for k in range(scans_per_map):
            t_scan = m.t_ns + (k + 1) * 100_000_000
            records.append(
                (
                    t_scan,
                    "/scan",
                    "sensor_msgs/msg/LaserScan",
                    _scan_message(store, serialization, t_scan, seq * 10 + k),
                )
            )
    records.sort(key=lambda r: r[0])
    topics: dict[str, str] = {}
    for _, topic, msgtype, _ in records:
        topics.setdefault(topic, msgtype)
    _WRITERS[fmt](path, kind, serialization, store, topics, records)
    return BuiltLog(path, fmt, serialization, list(maps))


def _write_ros1(
    path: Path, kind: str, ser: str, store: Any, topics: dict[str, str], records: list
) -> None:
    from rosbags.rosbag1 import Writer

    writer = Writer(path)
    if kind == "ros1-bz2":
        writer.set_compression(Writer.CompressionFormat.BZ2)
    with writer:
        conns = {
            topic: writer.add_connection(
                topic,
                msgtype,
                typestore=store,
                callerid="/slam",
                latching=1 if "map" in topic else 0,
            )
            for topic, msgtype in topics.items()
        }
        for t, topic, _, data in records:
            writer.write(conns[topic], t, data)


def _write_ros2(
    path: Path, kind: str, ser: str, store: Any, topics: dict[str, str], records: list
) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if kind == "mcap-dir" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conns = {
            topic: writer.add_connection(
                topic,
                msgtype,
                typestore=store,
                offered_qos_profiles=[_qos_latched()] if "map" in topic else [],
            )
            for topic, msgtype in topics.items()
        }
        for t, topic, _, data in records:
            writer.write(conns[topic], t, data)


def _write_mcap(
    path: Path, kind: str, ser: str, store: Any, topics: dict[str, str], records: list
) -> None:
    from mcap.writer import Writer

    ros1 = ser == "ros1"
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="ros1" if ros1 else "ros2", library="tests")
        channels = {}
        for topic, msgtype in topics.items():
            if ros1:
                msgdef, md5 = store.generate_msgdef(msgtype)
                name = msgtype.replace("/msg/", "/")
                schema = writer.register_schema(name, "ros1msg", msgdef.encode())
                meta = {
                    "md5sum": md5,
                    "callerid": "/slam",
                    "latching": "1" if "map" in topic else "0",
                }
                channels[topic] = writer.register_channel(topic, "ros1", schema, meta)
            else:
                msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
                schema = writer.register_schema(msgtype, "ros2msg", msgdef.encode())
                meta = (
                    {"offered_qos_profiles": _qos_yaml([_qos_latched()])} if "map" in topic else {}
                )
                channels[topic] = writer.register_channel(topic, "cdr", schema, meta)
        for seq, (t, topic, _, data) in enumerate(records):
            writer.add_message(channels[topic], t, data, t - 1000, seq)
        writer.finish()


_WRITERS: dict[str, Callable[..., None]] = {
    "ros1": _write_ros1,
    "db3": _write_ros2,
    "mcap-dir": _write_ros2,
    "mcap": _write_mcap,
}


def log_path(tmp_path: Path, kind: str, name: str = "in") -> Path:
    fmt, _ = FORMATS[kind]
    if fmt == "ros1":
        return tmp_path / f"{name}.bag"
    if fmt == "mcap":
        return tmp_path / f"{name}.mcap"
    return tmp_path / name


def read_all(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Topic -> [(log time ns, bytes)] of every message, via rose_logs.reader."""
    from rose_logs.reader import LogReader

    out: dict[str, list[tuple[int, bytes]]] = {}
    with LogReader(path) as reader:
        for m in reader.messages():
            out.setdefault(m.channel.topic, []).append((m.log_time_ns, bytes(m.data)))
    return out


def tree_bytes(path: Path) -> dict[str, bytes]:
    """File name -> bytes of a file or of every file in a folder (for untouched / determinism checks)."""
    if path.is_dir():
        return {p.name: p.read_bytes() for p in sorted(path.iterdir())}
    return {path.name: path.read_bytes()}


def session_maps(grids: Sequence[npt.NDArray[np.int8]], *, period_s: float = 5.0) -> list[MapMsg]:
    return [MapMsg(START_NS + round((i + 1) * period_s * 1e9), g) for i, g in enumerate(grids)]
