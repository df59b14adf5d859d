"""Connection metadata across formats: ROS 1 latching spellings, ROS 2 QoS spellings, required MCAP keys.

Input logs are written with the ``mcap`` package and rosbags directly (never ``rose_logs.writer``); the
map is a small drawn floor plan, so these tests need no data set.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
import yaml
from rosbags.rosbag2.metadata import dump_qos_v8
from rosbags.typesys import Stores, get_typestore

from rose_logs.reader import LogReader
from rose_logs.session import process_log
from rose_logs.storage.connections import qos_style, qos_yaml, transient_local_qos
from rose_logs.storage.records import parse_latching

T0_NS = 1_700_000_000_000_000_000
MAP_TYPE = "nav_msgs/msg/OccupancyGrid"
SCAN_TYPE = "sensor_msgs/msg/LaserScan"


def _floor_plan() -> npt.NDArray[np.int8]:
    """Two rooms and a corridor wall in a 120 x 160 grid, unknown outside (W about 0.06)."""
    grid = np.full((120, 160), -1, np.int8)
    grid[10:110, 10:150] = 0
    grid[[10, 109], 10:150] = 100
    grid[10:110, [10, 149]] = 100
    grid[60, 10:100] = 100
    grid[10:60, 80] = 100
    return grid


def _messages(serialization: str) -> list[tuple[int, str, bytes]]:
    """(log time, topic, bytes): two maps and a scan, serialised with rosbags' own typestore."""
    store = get_typestore(Stores.ROS1_NOETIC if serialization == "ros1" else Stores.ROS2_HUMBLE)
    t = store.types
    ser = store.serialize_ros1 if serialization == "ros1" else store.serialize_cdr
    grid = _floor_plan()
    out = []
    for k in range(2):
        t_ns = T0_NS + k * 1_000_000_000
        stamp = t["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=0)
        header_kw: dict[str, Any] = {"stamp": stamp, "frame_id": "map"}
        if serialization == "ros1":
            header_kw["seq"] = k
        header = t["std_msgs/msg/Header"](**header_kw)
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=-4.0, y=-3.0, z=0.0),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        info = t["nav_msgs/msg/MapMetaData"](
            map_load_time=stamp, resolution=0.05, width=160, height=120, origin=pose
        )
        msg = t[MAP_TYPE](header=header, info=info, data=grid.ravel())
        out.append((t_ns, "/map", bytes(ser(msg, MAP_TYPE))))
        scan = t[SCAN_TYPE](
            header=header,
            angle_min=-1.0,
            angle_max=1.0,
            angle_increment=0.5,
            time_increment=0.0,
            scan_time=0.1,
            range_min=0.1,
            range_max=10.0,
            ranges=np.ones(5, np.float32),
            intensities=np.zeros(0, np.float32),
        )
        out.append((t_ns + 1000, "/scan", bytes(ser(scan, SCAN_TYPE))))
    return out


def _write_mcap(path: Path, serialization: str, metadata: dict[str, dict[str, str]]) -> None:
    from mcap.writer import Writer

    store = get_typestore(Stores.ROS1_NOETIC if serialization == "ros1" else Stores.ROS2_HUMBLE)
    ros1 = serialization == "ros1"
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="ros1" if ros1 else "ros2", library="tests")
        channels = {}
        for topic, msgtype in (("/map", MAP_TYPE), ("/scan", SCAN_TYPE)):
            if ros1:
                msgdef, md5 = store.generate_msgdef(msgtype)
                schema = writer.register_schema(
                    msgtype.replace("/msg/", "/"), "ros1msg", msgdef.encode()
                )
                meta = {"md5sum": md5, **metadata[topic]}
            else:
                msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
                schema = writer.register_schema(msgtype, "ros2msg", msgdef.encode())
                meta = dict(metadata[topic])
            channels[topic] = writer.register_channel(topic, serialization, schema, meta)
        for seq, (t_ns, topic, data) in enumerate(_messages(serialization)):
            writer.add_message(channels[topic], t_ns, data, t_ns, seq)
        writer.finish()


def _mcap_channels(path: Path) -> dict[str, dict[str, str]]:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {c.topic: dict(c.metadata) for c in summary.channels.values()}


# -- ROS 1 latching ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1", 1),
        ("0", 0),
        ("true", 1),
        ("false", 0),
        (" True ", 1),
        ("FALSE", 0),
        ("yes", None),
        ("", None),
        (None, None),
    ],
)
def test_parse_latching_accepts_both_spellings(text: str | None, expected: int | None) -> None:
    assert parse_latching(text) == expected


@pytest.mark.parametrize("spelling", [("true", "false"), ("1", "0")])
def test_ros1_mcap_latching_is_read_and_kept(tmp_path: Path, spelling: tuple[str, str]) -> None:
    latched, volatile = spelling
    src = tmp_path / "in.mcap"
    _write_mcap(
        src,
        "ros1",
        {
            "/map": {"callerid": "/slam", "latching": latched},
            "/scan": {"callerid": "/laser", "latching": volatile},
        },
    )
    with LogReader(src) as reader:
        assert {c.topic: c.latching for c in reader.channels} == {"/map": 1, "/scan": 0}

    out = tmp_path / "out.bag"  # ROS 1 bag: latching lives in the connection header
    process_log(src, output_path=out)
    with LogReader(out) as reader:
        latching = {c.topic: c.latching for c in reader.channels}
    assert latching["/map"] == 1
    assert latching["/scan"] == 0
    assert latching["/map/rose/cleaned"] == 1  # follows the latched map
    assert latching["/map/rose/structure_score"] == 0


# -- ROS 2 QoS ---------------------------------------------------------------------------------
def test_qos_yaml_styles_round_trip() -> None:
    from rosbags.rosbag2.metadata import parse_qos

    profiles = [transient_local_qos(), transient_local_qos(5)]
    v8, v9 = qos_yaml(profiles, style="v8"), qos_yaml(profiles, style="v9")
    assert qos_style(v8) == "v8"
    assert qos_style(v9) == "v9"
    assert yaml.safe_load(v8)[0]["durability"] == 1  # RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL
    assert yaml.safe_load(v9)[0]["durability"] == "transient_local"
    assert parse_qos(v8) == parse_qos(v9) == profiles
    assert qos_style(dump_qos_v8(profiles)) == "v8"  # rosbags' own (flow-style) v8 text
    assert qos_style("") is None
    assert qos_style("{not: a list}") is None


@pytest.mark.parametrize("style", ["v8", "v9"])
def test_bare_mcap_added_topics_follow_the_input_qos_style(tmp_path: Path, style: str) -> None:
    src = tmp_path / "in.mcap"
    latched = qos_yaml([transient_local_qos()], style=style)  # type: ignore[arg-type]
    _write_mcap(src, "cdr", {"/map": {"offered_qos_profiles": latched}, "/scan": {}})
    with LogReader(src) as reader:
        assert reader.qos_style == style

    out = tmp_path / "out.mcap"
    process_log(src, output_path=out)
    channels = _mcap_channels(out)
    assert channels["/map"] == {"offered_qos_profiles": latched}  # copied as is
    # The ros2 profile requires offered_qos_profiles on every channel, ours and the input's.
    for topic, metadata in channels.items():
        assert qos_style(metadata["offered_qos_profiles"]) == style, topic
    cleaned = yaml.safe_load(channels["/map/rose/cleaned"]["offered_qos_profiles"])
    assert cleaned[0]["durability"] in {1, "transient_local"}
    score = yaml.safe_load(channels["/map/rose/structure_score"]["offered_qos_profiles"])
    assert score[0]["durability"] in {2, "volatile"}


@pytest.mark.parametrize("version", [8, 9])
@pytest.mark.parametrize("plugin", ["SQLITE3", "MCAP"])
def test_bag_folder_output_follows_the_input_qos_style(
    tmp_path: Path, version: int, plugin: str
) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer

    src = tmp_path / "in"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(src, version=version, storage_plugin=StoragePlugin[plugin]) as writer:
        conns = {
            "/map": writer.add_connection(
                "/map", MAP_TYPE, typestore=store, offered_qos_profiles=[transient_local_qos()]
            ),
            "/scan": writer.add_connection("/scan", SCAN_TYPE, typestore=store),
        }
        for t_ns, topic, data in _messages("cdr"):
            writer.write(conns[topic], t_ns, data)
    expected = "v8" if version == 8 else "v9"
    with LogReader(src) as reader:
        assert reader.qos_style == expected

    out = tmp_path / "out"
    process_log(src, output_path=out)
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == version
    styles = {
        t["topic_metadata"]["name"]: qos_style(t["topic_metadata"]["offered_qos_profiles"])
        for t in info["topics_with_message_count"]
    }
    assert styles["/map"] == expected
    for topic in ("/map/rose/cleaned", "/map/rose/structure_score", "/map/rose/walls"):
        assert styles[topic] == expected, topic
