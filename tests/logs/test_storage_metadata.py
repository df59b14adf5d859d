"""Connection metadata across formats: ROS 1 latching and definitions, ROS 2 QoS spellings, MCAP keys.

Input logs are written with the ``mcap`` package and rosbags directly (never ``rose_logs.writer``); the
map is a small drawn floor plan, so these tests need no data set.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

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
from rose_logs.storage.ros1_definitions import ROS1_FULL_TEXT
from rose_logs.storage.typesys import msgdef_for, typestore_for

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
    tmp_path: Path, version: Literal[8, 9], plugin: str
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


# -- ROS 1 message definitions -------------------------------------------------------------------
def _fields(text: str) -> list[str]:
    """Definition lines without comments and blanks, types without package (``std_msgs/Header`` ->
    ``Header``): what the md5sum depends on, whichever way the text qualifies names."""
    lines = (line.split("#", 1)[0].split() for line in text.splitlines())
    return [" ".join([words[0].rsplit("/", 1)[-1], *words[1:]]) for words in lines if words]


@pytest.mark.parametrize("msgtype", sorted(ROS1_FULL_TEXT))
def test_canonical_ros1_text_has_the_standard_md5_and_fields(msgtype: str) -> None:
    from rosbags.typesys import get_types_from_msg

    text = ROS1_FULL_TEXT[msgtype]
    noetic = get_typestore(Stores.ROS1_NOETIC)
    ours = typestore_for("ros1")
    generated, md5 = (noetic if msgtype in noetic.types else ours).generate_msgdef(msgtype)
    assert "#" in text or msgtype == "std_msgs/msg/Float32"  # comments kept
    assert _fields(text) == _fields(generated)  # same types, in the same order
    store = get_typestore(Stores.EMPTY)
    parts = text.split("=" * 80 + "\n")
    store.register(get_types_from_msg(parts[0], msgtype))
    for part in parts[1:]:
        header, body = part.split("\n", 1)
        store.register(get_types_from_msg(body, header.removeprefix("MSG: ").replace("/", "/msg/")))
    assert store.generate_msgdef(msgtype)[1] == md5
    assert msgdef_for(msgtype, "ros1") == (text, md5)


def test_ros1_output_stores_canonical_texts_and_keeps_the_inputs(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Writer

    src = tmp_path / "in.bag"
    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(src) as writer:  # rosbags stores its comment-free definitions
        conns = {
            topic: writer.add_connection(topic, msgtype, typestore=store, callerid="/slam")
            for topic, msgtype in (("/map", MAP_TYPE), ("/scan", SCAN_TYPE))
        }
        for t_ns, topic, data in _messages("ros1"):
            writer.write(conns[topic], t_ns, data)
    out = tmp_path / "out.bag"
    process_log(src, output_path=out)
    with LogReader(src) as a, LogReader(out) as b:
        before = {c.topic: c for c in a.channels}
        after = {c.topic: c for c in b.channels}
    for topic, channel in before.items():  # input texts kept as they are
        assert (after[topic].msgdef, after[topic].digest) == (channel.msgdef, channel.digest)
    for topic, msgtype in (
        ("/map/rose/cleaned", MAP_TYPE),
        ("/map/rose/structure_score", "std_msgs/msg/Float32"),
        ("/map/rose/walls", "visualization_msgs/msg/MarkerArray"),
    ):
        assert after[topic].msgdef == ROS1_FULL_TEXT[msgtype], topic
        assert after[topic].digest == typestore_for("ros1").generate_msgdef(msgtype)[1]
        # Published by rose-bag, not by the map's node.
        assert after[topic].callerid == "/rose_bag"
    assert after["/map"].callerid == "/slam"


def test_ros1_input_text_without_md5_is_kept(tmp_path: Path) -> None:
    """A ros1-profile MCAP channel without ``md5sum``: its text is copied, only the md5 computed."""
    from mcap.writer import Writer

    src = tmp_path / "in.mcap"
    text = ROS1_FULL_TEXT[MAP_TYPE]  # comments and all, as recorded by ROS
    with src.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="ros1", library="tests")
        schema = writer.register_schema("nav_msgs/OccupancyGrid", "ros1msg", text.encode())
        channel = writer.register_channel("/map", "ros1", schema, {"latching": "true"})
        for seq, (t_ns, topic, data) in enumerate(_messages("ros1")):
            if topic == "/map":
                writer.add_message(channel, t_ns, data, t_ns, seq)
        writer.finish()
    out = tmp_path / "out.bag"
    process_log(src, output_path=out)
    with LogReader(out) as reader:
        copied = next(c for c in reader.channels if c.topic == "/map")
    assert copied.msgdef == text
    assert copied.digest == "3381f2d731d4076ec5c71b0759edbe4e"  # nav_msgs/OccupancyGrid in ROS 1


def _humble_bag_with_a_custom_type(path: Path, fr079: list[npt.NDArray[np.int8]]) -> bytes:
    """A db3 bag as Humble's rosbag2 writes it (no message definitions stored) with a custom
    message type beside /map; returns the custom message's bytes."""
    import sqlite3

    from conftest import MapMsg, _map_message, typestore
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_types_from_msg

    store = typestore("cdr")
    store.register(get_types_from_msg("string mode\nfloat64 battery\n", "my_robot_msgs/msg/Status"))
    status = bytes(
        store.serialize_cdr(
            store.types["my_robot_msgs/msg/Status"](mode="explore", battery=0.5),
            "my_robot_msgs/msg/Status",
        )
    )
    with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as writer:
        grid = writer.add_connection("/map", "nav_msgs/msg/OccupancyGrid", typestore=store)
        custom = writer.add_connection("/status", "my_robot_msgs/msg/Status", typestore=store)
        for n, t in enumerate((1_000_000_000, 2_000_000_000)):
            writer.write(grid, t, _map_message(store, "cdr", MapMsg(t, fr079[n + 1]), n)[1])
            writer.write(custom, t + 1, status)
    db = sqlite3.connect(path / f"{path.name}.db3")
    db.execute("DELETE FROM message_definitions")  # what Humble's bags hold: nothing
    db.commit()
    db.close()
    return status


@pytest.mark.parametrize("fmt", ["db3", "mcap-dir", "mcap"])
def test_a_custom_type_without_definition_is_copied_and_stored_without_one(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]], fmt: str, caplog: pytest.LogCaptureFixture
) -> None:
    """Humble bags store no definitions, so their custom types have none: their messages are
    copied byte for byte (no output at all before), the output says "no definition" as Humble's
    bags do (an empty one made rosbags refuse to open the bag: hash mismatch), and a warning
    names the topic."""
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import MessageDefinitionFormat

    status = _humble_bag_with_a_custom_type(tmp_path / "humble", fr079)
    out = tmp_path / ("out.mcap" if fmt == "mcap" else "out")
    report = process_log(tmp_path / "humble", output_path=out, output_format=fmt)
    assert len(report.records) == 2
    assert "/status: no message definition of my_robot_msgs/msg/Status" in caplog.text
    with LogReader(out) as reader:
        copied = [bytes(m.data) for m in reader.messages() if m.channel.topic == "/status"]
    assert copied == [status, status]
    with AnyReader([out]) as reader:
        formats = {c.topic: c.msgdef.format for c in reader.connections}
    assert formats["/status"] == MessageDefinitionFormat.NONE
    assert formats["/map"] == MessageDefinitionFormat.MSG


def test_a_ros1_type_without_definition_goes_to_mcap_not_to_a_ros1_bag(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]], capsys: pytest.CaptureFixture[str]
) -> None:
    """A ROS 1 MCAP whose custom type has no definition: a ROS 1 bag cannot hold it (the error
    names the format that can, not db3, which refuses ROS 1 messages); MCAP copies it."""
    from conftest import MapMsg, _map_message, typestore
    from mcap.writer import Writer

    from rose_logs.cli import main

    store = typestore("ros1")
    src = tmp_path / "in.mcap"
    with src.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros1", library="test")
        msgdef, md5 = store.generate_msgdef("nav_msgs/msg/OccupancyGrid")
        grid = writer.register_channel(
            "/map",
            "ros1",
            writer.register_schema("nav_msgs/OccupancyGrid", "ros1msg", msgdef.encode()),
            {"md5sum": md5},
        )
        custom = writer.register_channel(
            "/status", "ros1", writer.register_schema("my_msgs/Status", "ros1msg", b""), {}
        )
        writer.add_message(grid, 1, _map_message(store, "ros1", MapMsg(1, fr079[0]), 1)[1], 1, 0)
        writer.add_message(custom, 2, b"\x00", 2, 1)
        writer.finish()
    assert main(["process", str(src), "-o", str(tmp_path / "o.bag"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "a ROS 1 bag needs the message definition of my_msgs/msg/Status" in err
    assert err.strip().endswith("write MCAP (--format mcap)") and "warning" not in err
    assert main(["process", str(src), "-o", str(tmp_path / "o.mcap"), "-q"]) == 0  # as it came
    with LogReader(tmp_path / "o.mcap") as reader:
        assert [bytes(m.data) for m in reader.messages(topics=["/status"])] == [b"\x00"]


def test_a_map_topic_with_two_publishers_is_said_to_be_one_session(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]
) -> None:
    """A map_server beside a SLAM node, both on /map: the session mixes their maps, and the break
    detector compares one's with the other's. A ROS 1 bag names the publishers: say so."""
    import logging

    from rosbags.rosbag1 import Writer

    src = tmp_path / "in.bag"
    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(src) as writer:
        maps = [
            writer.add_connection("/map", MAP_TYPE, typestore=store, callerid=node)
            for node in ("/slam", "/map_server")
        ]
        # A publisher that never sent a map (it counts for nothing).
        writer.add_connection("/map", MAP_TYPE, typestore=store, callerid="/idle")
        scans = writer.add_connection("/scan", SCAN_TYPE, typestore=store, callerid="/laser")
        map_count = 0
        for t_ns, topic, data in _messages("ros1"):
            if topic == "/map":
                writer.write(maps[map_count % 2], t_ns, data)
                map_count += 1
            else:
                writer.write(scans, t_ns, data)
    with caplog.at_level(logging.WARNING):
        report = process_log(src, output_path=None)
    said = [r.getMessage() for r in caplog.records if "publishers" in r.getMessage()]
    assert said == [
        "/map: maps from 2 publishers (/map_server, /slam) are analysed as one session: the "
        "break detector compares one's maps with the other's (-t picks no publisher)"
    ]
    assert len(report.records) == map_count == 2
    from rose_logs.cli import main

    assert main(["info", str(src)]) == 0
    assert (
        "  publishers   /map_server, /slam  (analysed as one session)\n" in capsys.readouterr().out
    )
    caplog.clear()
    one = tmp_path / "one.bag"
    with Writer(one) as writer:  # one publisher, and one that sent nothing: nothing to say
        conns = {
            topic: writer.add_connection(topic, msgtype, typestore=store, callerid="/slam")
            for topic, msgtype in (("/map", MAP_TYPE), ("/scan", SCAN_TYPE))
        }
        writer.add_connection("/map", MAP_TYPE, typestore=store, callerid="/idle")
        for t_ns, topic, data in _messages("ros1"):
            writer.write(conns[topic], t_ns, data)
    with caplog.at_level(logging.WARNING):
        process_log(one, output_path=None)
    assert not [r for r in caplog.records if "publishers" in r.getMessage()]


def _ros2_mcap_writer(stream: Any) -> tuple[Any, int]:
    """An ``mcap`` Writer started on ``stream`` (ROS 2 profile) and the id of its ``/map`` channel
    (CDR ``nav_msgs/msg/OccupancyGrid``)."""
    from mcap.writer import Writer

    msgdef, _ = get_typestore(Stores.ROS2_HUMBLE).generate_msgdef(MAP_TYPE, ros_version=2)
    writer = Writer(stream)
    writer.start(profile="ros2", library="tests")
    schema = writer.register_schema(MAP_TYPE, "ros2msg", msgdef.encode())
    return writer, writer.register_channel("/map", "cdr", schema, {})


def test_schemas_of_other_encodings_are_copied_as_stored(tmp_path: Path) -> None:
    """A protobuf channel beside the maps: its schema, a FileDescriptorSet, is binary. Read as
    text and written back, its bytes that are no UTF-8 became U+FFFD and the channel could no
    longer be decoded. A JSON channel without schema got an empty schema record."""
    from mcap.reader import make_reader

    # A FileDescriptorSet's start: field 1 with a two-byte varint length (0x95 0x01).
    descriptor = b"\x0a\x95\x01\x0a\x1fgoogle/protobuf/timestamp.proto\xff\xfe"
    src = tmp_path / "in.mcap"
    with src.open("wb") as f:
        writer, maps = _ros2_mcap_writer(f)
        proto = writer.register_schema("google.protobuf.Timestamp", "protobuf", descriptor)
        stamps = writer.register_channel("/stamp", "protobuf", proto, {})
        notes = writer.register_channel("/notes", "json", 0, {})  # no schema (id 0)
        for seq, (t_ns, topic, data) in enumerate(_messages("cdr")):
            if topic == "/map":
                writer.add_message(maps, t_ns, data, t_ns, seq)
                writer.add_message(stamps, t_ns, b"\x08\x96\x01", t_ns, seq)
                writer.add_message(notes, t_ns, b'{"note": 1}', t_ns, seq)
        writer.finish()
    out = tmp_path / "out.mcap"
    process_log(src, output_path=out)
    with out.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    copied = [s for s in summary.schemas.values() if s.encoding == "protobuf"]
    assert [(s.name, s.data) for s in copied] == [("google.protobuf.Timestamp", descriptor)]
    # A channel without schema stays one, not one with an empty schema record.
    assert [c.schema_id for c in summary.channels.values() if c.topic == "/notes"] == [0]
    assert all(s.name for s in summary.schemas.values())


def test_an_mcap_files_metadata_and_attachments_are_copied(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Records of no channel (a robot's name, an attached URDF) were left out of the output."""
    import logging

    from mcap.reader import make_reader

    src = tmp_path / "in.mcap"
    with src.open("wb") as f:
        writer, maps = _ros2_mcap_writer(f)
        for seq, (t_ns, topic, data) in enumerate(_messages("cdr")):
            if topic == "/map":
                writer.add_message(maps, t_ns, data, t_ns, seq)
        writer.add_metadata("robot", {"name": "r2", "serial": "42"})
        writer.add_attachment(T0_NS, T0_NS + 1, "robot.urdf", "text/xml", b"<robot/>\xff")
        writer.finish()

    def records(path: Path) -> tuple[list[Any], list[Any]]:
        with path.open("rb") as f:
            reader = make_reader(f)
            return (
                [(m.name, m.metadata) for m in reader.iter_metadata()],
                [
                    (a.create_time, a.log_time, a.name, a.media_type, a.data)
                    for a in reader.iter_attachments()
                ],
            )

    out = tmp_path / "out.mcap"
    process_log(src, output_path=out)
    assert records(out) == records(src) != ([], [])
    with caplog.at_level(logging.WARNING):  # a bag folder has no place for them: said
        process_log(src, output_path=tmp_path / "out_db3", output_format="db3")
    assert any(
        "2 MCAP metadata / attachment record(s) are not copied" in r.getMessage()
        for r in caplog.records
    )


@pytest.mark.parametrize("summary", ["statistics only", "none"])
def test_metadata_and_attachments_an_mcap_summary_does_not_index_are_copied(
    tmp_path: Path, summary: str
) -> None:
    """The summary's metadata and attachment indexes are optional (a writer's index_types): a
    file written without them had its records left out of the output without a word, though its
    statistics counted them."""
    from mcap.writer import IndexType, Writer

    src = tmp_path / "in.mcap"
    options: dict[str, Any] = {"index_types": IndexType.CHUNK | IndexType.MESSAGE}
    if summary == "none":
        options.update(use_statistics=False, use_summary_offsets=False, index_types=IndexType.NONE)
    with src.open("wb") as f:
        writer = _ros2_maps_mcap(Writer(f, **options))
        writer.add_metadata("robot", {"name": "r2"})
        writer.add_attachment(T0_NS, T0_NS, "robot.urdf", "text/xml", b"<robot/>")
        writer.finish()
    out = tmp_path / "out.mcap"
    process_log(src, output_path=out)
    assert _records_of(out) == (["robot"], ["robot.urdf"])


def _mcap_file_again(
    path: Path, plain: bytes, keep: Any, records: int, *, summary: bool = True
) -> None:
    """``path`` written again from the MCAP file ``plain`` (rosbags' storage file of a bag):
    its messages whose log time ``keep`` keeps, its metadata records (rosbag2's) and ``records``
    metadata and attachment records of our own after them (``summary`` False: a file without
    one)."""
    import io

    from mcap.reader import make_reader
    from mcap.writer import IndexType, Writer

    reader = make_reader(io.BytesIO(plain))
    found = reader.get_summary()
    assert found is not None
    options: dict[str, Any] = {}
    if not summary:
        options = {
            "use_summary_offsets": False,
            "use_statistics": False,
            "index_types": IndexType.NONE,
            "repeat_channels": False,
            "repeat_schemas": False,
        }
    with path.open("wb") as f:
        writer = Writer(f, **options)
        writer.start(profile="ros2", library="tests")
        schemas = {
            s.id: writer.register_schema(s.name, s.encoding, s.data) for s in found.schemas.values()
        }
        channels = {
            c.id: writer.register_channel(
                c.topic, c.message_encoding, schemas[c.schema_id], c.metadata
            )
            for c in found.channels.values()
        }
        for _, channel, message in reader.iter_messages():
            if keep(message.log_time):
                writer.add_message(
                    channels[channel.id], message.log_time, message.data, message.log_time
                )
        for metadata in reader.iter_metadata():
            writer.add_metadata(metadata.name, metadata.metadata)
        for k in range(records):
            writer.add_metadata(f"{path.stem}-{k}", {"robot": "r2"})
            writer.add_attachment(T0_NS, T0_NS, f"{path.stem}-{k}.urdf", "text/xml", b"<robot/>")
        writer.finish()


def _ros2_maps_mcap(writer: Any) -> Any:
    """``writer`` (an ``mcap`` Writer, not started) started as a ROS 2 MCAP file holding the
    test log's ``/map`` messages; the caller adds records and finishes it."""
    msgdef, _ = get_typestore(Stores.ROS2_HUMBLE).generate_msgdef(MAP_TYPE, ros_version=2)
    writer.start(profile="ros2", library="tests")
    schema = writer.register_schema(MAP_TYPE, "ros2msg", msgdef.encode())
    maps = writer.register_channel("/map", "cdr", schema, {})
    for seq, (t_ns, topic, data) in enumerate(_messages("cdr")):
        if topic == "/map":
            writer.add_message(maps, t_ns, data, t_ns, seq)
    return writer


def _bookkeeping_of(path: Path) -> dict[str, str]:
    """The MCAP file ``path``'s first ``rosbag2`` metadata record (rosbag2's of its bag)."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        return next(m.metadata for m in make_reader(f).iter_metadata() if m.name == "rosbag2")


def _records_of(path: Path) -> tuple[list[str], list[str]]:
    """The names of the MCAP file ``path``'s metadata and attachment records."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        reader = make_reader(f)
        return [m.name for m in reader.iter_metadata()], [a.name for a in reader.iter_attachments()]


@pytest.mark.parametrize("layout", ["one file", "split", "split, no summary"])
def test_a_bag_folders_mcap_metadata_and_attachments_are_copied(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, layout: str
) -> None:
    """A ROS 2 bag folder of MCAP storage lost its MCAP files' metadata and attachment records
    without a word (a bare MCAP file's went into an MCAP output, or a warning said why not).
    Now the same; of rosbag2's own record of the bag's metadata (one in each file) the first
    file's only: rosbag2 reads a bare MCAP file's format version (its QoS spelling) and
    custom_data from it, and the files' records say the same of those."""
    import logging

    from rosbags.rosbag2 import StoragePlugin, Writer

    src = tmp_path / "in"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(src, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        maps = writer.add_connection("/map", MAP_TYPE, typestore=store)
        for t_ns, topic, data in _messages("cdr"):
            if topic == "/map":
                writer.write(maps, t_ns, data)
    whole = src / "in.mcap"
    plain = whole.read_bytes()
    if layout == "one file":
        _mcap_file_again(whole, plain, lambda t: True, 1)
        files = [whole]
    else:  # at half its time, as rosbag2's --max-bag-duration
        whole.unlink()
        files = [src / "in_0.mcap", src / "in_1.mcap"]
        _mcap_file_again(files[0], plain, lambda t: t < T0_NS + 500_000_000, 1)
        _mcap_file_again(
            files[1], plain, lambda t: t >= T0_NS + 500_000_000, 2, summary=layout == "split"
        )
        meta = src / "metadata.yaml"
        listed = "".join(f"  - {f.name}\n" for f in files)
        meta.write_text(meta.read_text().replace("  - in.mcap\n", listed))
    ours = [name for f in files for name in _records_of(f)[0] if name != "rosbag2"]
    assert [_records_of(f)[0][0] for f in files] == ["rosbag2"] * len(files)

    out = tmp_path / "out.mcap"
    process_log(src, output_path=out)
    assert _records_of(out) == (["rosbag2", *ours], [f"{name}.urdf" for name in ours])
    assert _bookkeeping_of(out) == _bookkeeping_of(files[0])
    with caplog.at_level(logging.WARNING):  # rosbags' writer has no way to add them: said once
        process_log(src, output_path=tmp_path / "out_dir", output_format="mcap-dir")
    said = [r.getMessage() for r in caplog.records if "are not copied" in r.getMessage()]
    assert len(said) == 1 and f"{2 * len(ours) + 1} MCAP metadata / attachment" in said[0]
    assert _records_of(tmp_path / "out_dir" / "out_dir.mcap") == (["rosbag2"], [])  # its own
    # A storage file read alone: its records, rosbag2's too, as any MCAP file's.
    process_log(files[0], output_path=tmp_path / "alone.mcap")
    assert _records_of(tmp_path / "alone.mcap")[0] == ["rosbag2", f"{files[0].stem}-0"]


@pytest.mark.parametrize("plugin", ["SQLITE3", "MCAP"])
def test_a_bags_custom_data_is_copied(
    tmp_path: Path, plugin: str, caplog: pytest.LogCaptureFixture
) -> None:
    """``ros2 bag record --custom-data`` (a robot's name, a run's id) was left out of the output
    bag's metadata.yaml without a word; values are text as spelled (rosbag2 reads no types)."""
    import logging

    from rosbags.rosbag2 import StoragePlugin, Writer

    src = tmp_path / "in"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(src, version=9, storage_plugin=StoragePlugin[plugin]) as writer:
        writer.set_custom_data("robot", "r2")
        writer.set_custom_data("run", "2026-12-06")
        maps = writer.add_connection("/map", MAP_TYPE, typestore=store)
        for t_ns, topic, data in _messages("cdr"):
            if topic == "/map":
                writer.write(maps, t_ns, data)
    metadata = src / "metadata.yaml"  # as rosbag2 (yaml-cpp) spells them: unquoted
    metadata.write_text(metadata.read_text().replace("'2026-12-06'", "2026-12-06") + "\n")

    def custom_data(bag: Path) -> Any:
        info = yaml.load((bag / "metadata.yaml").read_text(), Loader=yaml.BaseLoader)
        return info["rosbag2_bagfile_information"]["custom_data"]

    out = tmp_path / "out"
    process_log(src, output_path=out)
    assert custom_data(out) == custom_data(src) == {"robot": "r2", "run": "2026-12-06"}
    with caplog.at_level(logging.WARNING):  # an MCAP file has no place for it: said
        process_log(src, output_path=tmp_path / "out.mcap")
    assert any("custom_data (robot, run) is not copied" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_a_connection_given_twice_keeps_its_messages_on_its_own(
    tmp_path: Path, serialization: str
) -> None:
    """Channels alike in every way (a merged MCAP file, a ROS 1 node that reconnected) are one
    connection of a rosbags output: the second's messages went to the first connection of their
    topic and type, another publisher's (ROS 1) or one of other QoS (ROS 2)."""
    from mcap.writer import Writer
    from rosbags.highlevel import AnyReader

    from rose_logs.storage.connections import default_qos

    store = get_typestore(Stores.ROS1_NOETIC if serialization == "ros1" else Stores.ROS2_HUMBLE)
    ros1 = serialization == "ros1"
    if ros1:
        msgdef, md5 = store.generate_msgdef(MAP_TYPE)
        name, encoding = "nav_msgs/OccupancyGrid", "ros1msg"
        metas = [
            {"callerid": node, "latching": "1", "md5sum": md5}
            for node in ("/map_server", "/slam", "/slam")
        ]
    else:
        msgdef, _ = store.generate_msgdef(MAP_TYPE, ros_version=2)
        name, encoding = MAP_TYPE, "ros2msg"
        metas = [
            {"offered_qos_profiles": qos_yaml([qos])}
            for qos in (default_qos(), transient_local_qos(), transient_local_qos())
        ]
    maps = [data for _t, topic, data in _messages(serialization) if topic == "/map"]
    src = tmp_path / "in.mcap"
    with src.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="ros1" if ros1 else "ros2", library="tests")
        schema = writer.register_schema(name, encoding, msgdef.encode())
        ids = [writer.register_channel("/map", serialization, schema, m) for m in metas]
        for k in range(6):  # channel k % 3
            writer.add_message(ids[k % 3], T0_NS + k * 10**9, maps[k % 2], T0_NS + k * 10**9, k)
        writer.finish()
    out = tmp_path / ("out.bag" if ros1 else "out")
    process_log(src, output_path=out, output_format="ros1" if ros1 else "db3")

    def publisher(ext: Any) -> str:
        if ros1:
            return str(ext.callerid)
        return str(ext.offered_qos_profiles[0].durability.name)

    with AnyReader([out]) as reader:
        got = [publisher(c.ext) for c, _t, _d in reader.messages() if c.topic == "/map"]
    first, second = ("/map_server", "/slam") if ros1 else ("VOLATILE", "TRANSIENT_LOCAL")
    assert got == [first, second, second] * 2


@pytest.mark.parametrize(
    ("change", "said"),
    [
        ("UPDATE messages SET data = NULL WHERE id = 2", "holds NULL, not its bytes"),
        ("UPDATE messages SET data = 'hello' WHERE id = 2", "holds the text 'hello', not its"),
        ("UPDATE messages SET data = 7 WHERE id = 2", "holds the number 7, not its bytes"),
        ("UPDATE messages SET timestamp = -5 WHERE id = 2", "has no valid time (the number -5)"),
        ("UPDATE messages SET timestamp = NULL WHERE id = 2", "has no valid time (NULL)"),
        ("UPDATE messages SET timestamp = 'x' WHERE id = 2", "has no valid time (the text 'x')"),
        ("UPDATE messages SET timestamp = 1e300 WHERE id = 2", "no valid time (the number 1e+300)"),
    ],
)
def test_a_sqlite_row_that_holds_no_message_is_named_as_damage_of_the_input(
    tmp_path: Path,
    fr079: list[npt.NDArray[np.int8]],
    change: str,
    said: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SQLite columns take any type: a NULL or a text where a message's bytes belong, or a time
    that is no ROS time, raised a TypeError traceback while copying (or blamed the output)."""
    import sqlite3

    from conftest import build_log, session_maps

    from rose_logs.cli import main

    bag = build_log(tmp_path / "in", "db3", session_maps(fr079[:3]), scans_per_map=0).path
    (storage,) = bag.glob("*.db3")
    db = sqlite3.connect(storage)
    db.execute("PRAGMA writable_schema = ON")  # rosbag2 declares NOT NULL; the damage does not
    db.execute(
        "UPDATE sqlite_master SET sql = replace(replace(sql, 'data BLOB NOT NULL', 'data BLOB'), "
        "'timestamp INTEGER NOT NULL', 'timestamp INTEGER') WHERE name = 'messages'"
    )
    db.commit()
    db.close()
    db = sqlite3.connect(storage)
    db.execute(change)
    db.commit()
    db.close()
    # Where the damaged row sorts: first (NULL, a negative time), last (a text, a huge time), or
    # in its place (bad data): --salvage keeps the messages before it, and says so when any are.
    value = change.split()[5]
    before = {"-5": 0, "NULL": 0, "'x'": 2, "1e300": 2}[value] if "timestamp" in change else 1
    hint = f"; --salvage keeps the {before} message(s) before it" if before else ""
    out = tmp_path / "out.mcap"
    assert main(["process", str(bag), "-o", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {bag}: ")
    assert said in err and err.endswith(f"{hint}\n")
    assert not out.exists()
    assert main(["process", str(bag), "-o", str(out), "-q", "--salvage"]) == (4 if before else 1)
    assert said in capsys.readouterr().err
    assert out.is_file() == bool(before)


def _strings_db3(path: Path, times: list[int], topics: list[int], *, index: bool) -> None:
    """A ROS 2 bag folder (SQLite) of short strings, the ``i``-th on ``/t<topics[i]>`` at ``T0_NS
    + times[i]``, inserted in that order; without rosbag2's ``timestamp_idx`` unless ``index``."""
    import contextlib
    import sqlite3

    from rosbags.rosbag2 import StoragePlugin, Writer

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conns = {
            k: writer.add_connection(f"/t{k}", "std_msgs/msg/String", typestore=store)
            for k in sorted(set(topics))
        }
        for i, (time, topic) in enumerate(zip(times, topics, strict=True)):
            text = f"{i}".encode()
            data = b"\x00\x01\x00\x00" + (len(text) + 1).to_bytes(4, "little") + text + b"\x00"
            writer.write(conns[topic], T0_NS + time, data)
    if not index:
        (storage,) = path.glob("*.db3")
        with contextlib.closing(sqlite3.connect(storage)) as db:
            db.execute("DROP INDEX timestamp_idx")
            db.commit()


@pytest.mark.parametrize("seed", range(6))
def test_a_sqlite_bag_without_its_time_index_is_read_in_row_order_not_sorted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    """A SQLite bag without rosbag2's index of its messages' times (older rosbag2, or an index
    dropped): rosbags' query ``ORDER BY timestamp`` had SQLite sort every wanted row, data
    included, in a temporary B-tree (300,000 messages of 1 kB: 318 MB on the temporary disk)
    before the first message. Rows inserted in time order are read in the table's order, in the
    order the sort gave (ties too: in the order SQLite's plan scans them); rows out of order are
    sorted as before. Same messages and order as rosbags' reading, with and without the index,
    for topic subsets."""
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    topics = rng.integers(0, 6, n).tolist()
    order = seed % 3  # 0: in time order (ties); 1: each topic in order, not the whole; 2: random
    times = np.cumsum(rng.integers(0, 3, n))
    if order == 1:
        times = times + np.asarray(topics) * 7  # each topic's shifted: later than others' after
    elif order == 2:
        times = rng.integers(0, 80, n)
    sorted_query = 0
    sorts = Sqlite3Reader.messages

    def counted(self: Any, *args: Any, **kwargs: Any) -> Any:
        nonlocal sorted_query
        sorted_query += 1
        return sorts(self, *args, **kwargs)

    for index in (True, False):
        bag = tmp_path / f"bag-{index}"
        _strings_db3(bag, [int(t) for t in times], topics, index=index)
        # Up to four topics SQLite scans the table once per topic, else once (SQLite 3.4x).
        for wanted in (None, {"/t0"}, {"/t1", "/t3"}, {f"/t{k}" for k in range(5)}):
            with Reader(bag) as reader:
                conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
                expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages(conns)]
            monkeypatch.setattr(Sqlite3Reader, "messages", counted)
            sorted_query = 0
            with LogReader(bag) as ours:
                got = [
                    (m.channel.topic, m.log_time_ns, bytes(m.data))
                    for m in ours.messages(topics=wanted)
                ]
            monkeypatch.setattr(Sqlite3Reader, "messages", sorts)
            assert got == expected
            if not index and order == 0 and expected:  # read in row order: nothing sorted
                assert sorted_query == 0


def test_a_storage_file_listed_twice_in_metadata_is_refused_not_read_twice(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]], capsys: pytest.CaptureFixture[str]
) -> None:
    from conftest import build_log, session_maps

    from rose_logs.cli import main

    bag = build_log(tmp_path / "in", "db3", session_maps(fr079[:2]), scans_per_map=0).path
    meta = bag / "metadata.yaml"
    info = yaml.safe_load(meta.read_text())
    files = info["rosbag2_bagfile_information"]["relative_file_paths"]
    info["rosbag2_bagfile_information"]["relative_file_paths"] = files + files
    meta.write_text(yaml.safe_dump(info))
    assert main(["process", str(bag), "--no-output", "-q"]) == 1
    err = capsys.readouterr().err
    assert err == f"error: {bag}: metadata.yaml lists the storage file {files[0]} more than once\n"


@pytest.mark.parametrize("kind", ["db3", "mcap-dir"])
@pytest.mark.parametrize("salvage", [False, True])
def test_a_storage_file_that_is_a_folder_is_named_so(
    tmp_path: Path,
    fr079: list[npt.NDArray[np.int8]],
    capsys: pytest.CaptureFixture[str],
    kind: str,
    salvage: bool,
) -> None:
    """A storage file that metadata.yaml lists but is a folder read "corrupt or truncated log
    (... disk I/O error)" (SQLite) or "(... Is a directory.)" (MCAP): it is named, as a folder."""
    from conftest import build_log, session_maps

    from rose_logs.cli import main

    bag = build_log(tmp_path / "in", kind, session_maps(fr079[:2]), scans_per_map=0).path
    (storage,) = (p for p in bag.iterdir() if p.name != "metadata.yaml")
    storage.unlink()
    storage.mkdir()
    args = ["process", str(bag), "--no-output", "-q"] + (["--salvage"] if salvage else [])
    assert main(args) == 1
    err = capsys.readouterr().err
    assert err == (
        f"error: {storage}: a folder, not a file, where the bag's metadata.yaml lists a "
        "storage file\n"
    )


def test_a_type_missing_on_either_side_is_named_so() -> None:
    """A storage topic with an empty type read "..., the storage )"."""
    from rose_logs.storage.integrity import type_mismatches

    assert type_mismatches({"/map": "nav_msgs/msg/OccupancyGrid"}, {"/map": ""}) == [
        "/map: metadata.yaml says nav_msgs/msg/OccupancyGrid, the storage no type"
    ]
    assert type_mismatches({"/map": ""}, {"/map": "nav_msgs/msg/OccupancyGrid"}) == [
        "/map: metadata.yaml says no type, the storage nav_msgs/msg/OccupancyGrid"
    ]


@pytest.mark.parametrize("summary", [True, False])
def test_attachments_are_copied_one_at_a_time(tmp_path: Path, summary: bool) -> None:
    """An MCAP file's attachments (a map, a point cloud: a gigabyte each) were all read into
    memory at once to be copied, and a file without summary held them through the session: the
    peak was their sum. They are read one at a time as they are written."""
    import tracemalloc

    from mcap.reader import make_reader
    from mcap.writer import IndexType, Writer

    size, count = 16 * 2**20, 8
    src = tmp_path / "in.mcap"
    with src.open("wb") as f:
        options: dict[str, Any] = (
            {}
            if summary
            else {
                "use_summary_offsets": False,
                "use_statistics": False,
                "index_types": IndexType.NONE,
                "repeat_channels": False,
                "repeat_schemas": False,
            }
        )
        writer = _ros2_maps_mcap(Writer(f, **options))
        for k in range(count):
            writer.add_attachment(
                T0_NS, T0_NS, f"part{k}.bin", "application/octet-stream", bytes([k]) * size
            )
        writer.finish()
    out = tmp_path / "out.mcap"
    tracemalloc.start()
    try:
        process_log(src, output_path=out)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < count * size / 2, f"{peak / 2**20:.0f} MiB"
    with out.open("rb") as f:
        attached = [(a.name, len(a.data), a.data[:1]) for a in make_reader(f).iter_attachments()]
    assert attached == [(f"part{k}.bin", size, bytes([k])) for k in range(count)]


@pytest.mark.parametrize(("value", "text_parses"), [("r2", 0), ("2026-12-06", 1)])
def test_custom_data_read_as_text_is_not_parsed_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, value: str, text_parses: int
) -> None:
    """A bag with custom_data had its metadata.yaml parsed a second time, every value as text
    (3,000 topics: 1.3 s), also when the first parse read them all as text already, spelled as
    they are; only a value read as something else (a date, a number) needs it."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    src = tmp_path / "in"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(src, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        writer.set_custom_data("robot", value)
        maps = writer.add_connection("/map", MAP_TYPE, typestore=store)
        for t_ns, topic, data in _messages("cdr"):
            if topic == "/map":
                writer.write(maps, t_ns, data)
    metadata = src / "metadata.yaml"  # as rosbag2 (yaml-cpp) spells them: unquoted
    metadata.write_text(metadata.read_text().replace(f"'{value}'", value))
    as_text: list[object] = []
    load = yaml.load

    def counted(stream: Any, Loader: Any) -> Any:
        if Loader is yaml.BaseLoader:
            as_text.append(stream)
        return load(stream, Loader=Loader)

    monkeypatch.setattr(yaml, "load", counted)
    out = tmp_path / "out"
    process_log(src, output_path=out)
    assert len(as_text) == text_parses
    monkeypatch.undo()
    copied = yaml.load((out / "metadata.yaml").read_text(), Loader=yaml.BaseLoader)
    assert copied["rosbag2_bagfile_information"]["custom_data"] == {"robot": value}


def test_a_bag_folders_metadata_is_read_once_and_a_rewrite_after_it_is_seen(
    tmp_path: Path,
) -> None:
    """metadata.yaml was parsed up to three times a run (the format check, the reader's open,
    custom_data; seconds each for a 3,000-topic bag), each time from the file as it then was: a
    rewrite between the reads gave the reader two views of one bag (its format from one file,
    its checks and rosbags' reading from another; custom_data asked after the reading from a
    third). Now it is read once, when the reader is made, and a rewrite after that is an error
    saying the file changed, not a mix."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from rose_logs.errors import LogReadError

    src = tmp_path / "in"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(src, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        writer.set_custom_data("run", "2026-12-06")  # read as a date: parsed again as text
        maps = writer.add_connection("/map", MAP_TYPE, typestore=store)
        for t_ns, topic, data in _messages("cdr"):
            if topic == "/map":
                writer.write(maps, t_ns, data)
    metadata = src / "metadata.yaml"
    original = metadata.read_text().replace("'2026-12-06'", "2026-12-06")  # as rosbag2 spells it
    metadata.write_text(original)
    rewritten = original.replace("2026-12-06", "2027-01-01")
    # Read, then metadata.yaml rewritten: custom_data is the bag's as it was read.
    with LogReader(src) as reader:
        assert sum(1 for _ in reader.messages()) > 0
        metadata.write_text(rewritten + "\n")
        assert reader.custom_data == {"run": "2026-12-06"}
    # Rewritten between the reader's making and its opening: said, not read as a mix.
    metadata.write_text(original)
    reader = LogReader(src)
    metadata.write_text(rewritten + "\n")
    with pytest.raises(LogReadError, match=r"metadata\.yaml: the file changed while it was read"):
        reader.open()


def rewritten_after_its_first_parse(monkeypatch: pytest.MonkeyPatch, metadata: Path) -> None:
    """Act as a program that rewrites ``metadata`` (a new file of one more line put in its place)
    as soon as rose-bag has parsed it once: every later read gets the new file."""
    import rose_logs.formats

    parse = rose_logs.formats.load_yaml
    done: list[bool] = []

    def parse_then_rewrite(text: bytes) -> Any:
        parsed = parse(text)
        if not done:
            done.append(True)
            new = metadata.with_name("metadata.yaml.new")
            new.write_bytes(metadata.read_bytes() + b"# rewritten\n")
            new.replace(metadata)
        return parsed

    monkeypatch.setattr(rose_logs.formats, "load_yaml", parse_then_rewrite)


def test_process_reads_the_input_metadata_once_for_the_output_format_and_the_reading(
    tmp_path: Path,
    fr079: list[npt.NDArray[np.int8]],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``rose-bag process BAG -o OUT`` (no suffix naming a format: OUT in the input's) read the
    bag's metadata.yaml for the output's format, then again for the reading (seconds each for a
    bag of thousands of topics), and a rewrite in between went unseen: the output's format was
    taken from one file, the messages from another. Now the reader that chose the format reads
    the bag, and a rewrite after its one read is said."""
    from conftest import build_log, session_maps

    from rose_logs.cli import main

    bag = build_log(tmp_path / "in", "db3", session_maps(fr079[:2]), scans_per_map=0).path
    meta = (bag / "metadata.yaml").absolute()
    for out in (tmp_path / "out", tmp_path / "out.mcpa"):  # (the second: a suffix warning too)
        rewritten_after_its_first_parse(monkeypatch, meta)
        assert main(["process", str(bag), "-o", str(out), "-q"]) == 1
        err = capsys.readouterr().err
        assert f"error: {meta}: the file changed while it was read" in err
        assert not out.exists()
        monkeypatch.undo()
        meta.write_bytes(meta.read_bytes().replace(b"# rewritten\n", b""))
        assert main(["process", str(bag), "-o", str(out), "-q"]) == 0
        assert (out / "metadata.yaml").is_file()  # a bag folder, as the input


def test_batch_cleaned_reads_a_bags_metadata_once(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``rose-bag batch --cleaned`` read each bag folder's metadata.yaml for the cleaned log's
    format, then again for the reading (seconds each for thousands of topics), a rewrite in
    between unseen. Now the reader that gave the format reads the bag: a rewrite after its one
    read is the recording's error."""
    from conftest import build_log, session_maps

    from rose_logs.batch import RecordingOptions, run_batch

    bag = build_log(tmp_path / "in", "db3", session_maps(fr079[:2]), scans_per_map=0).path
    meta = (bag / "metadata.yaml").absolute()
    rewritten_after_its_first_parse(monkeypatch, meta)
    report = run_batch([bag], tmp_path / "out", options=RecordingOptions(cleaned=True))
    (result,) = report.results
    assert result.status == "error"
    assert result.format == "db3"
    assert f"{meta}: the file changed while it was read" in (result.error or "")
    monkeypatch.undo()
    report = run_batch([bag], tmp_path / "out", options=RecordingOptions(cleaned=True), force=True)
    assert [r.status for r in report.results] == ["ok"]
