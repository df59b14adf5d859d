"""Logs of many topics (a robot records one per sensor, diagnostics, tf, parameters): every topic
and message is copied to the output, in each format, whatever the number of topics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import build_log, log_path, read_all, session_maps, tree_bytes

from rose_logs.cli import main
from rose_logs.reader import LogReader

#: Many more topics than the other tests' logs; enough that each topic's connections are looked up
#: among hundreds (the writers' indexes), few enough to keep the suite quick.
TOPICS = 300


@pytest.mark.parametrize("kind", ["ros1", "db3", "mcap-dir", "mcap-ros2"])
def test_a_log_of_hundreds_of_topics_keeps_every_topic_and_message(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]], kind: str
) -> None:
    """Each of 300 small topics comes out with its type, its messages' bytes and times, and its
    count, beside the map's derived topics; a second run writes the same bytes."""
    log = build_log(
        log_path(tmp_path, kind),
        kind,
        session_maps(fr079[:2]),
        scans_per_map=1,
        small_topics=TOPICS,
    )
    out = log_path(tmp_path, kind, "out")
    assert main(["process", str(log.path), "-o", str(out), "-q"]) == 0

    given, got = read_all(log.path), read_all(out)
    assert len(given) == TOPICS + 2  # the small topics, /map, /scan
    assert {topic: got.get(topic) for topic in given} == given
    assert set(got) - set(given) == {
        "/map/rose/cleaned",
        "/map/rose/structure_score",
        "/map/rose/walls",
    }
    with LogReader(log.path) as src, LogReader(out) as dst:
        types = {c.topic: c.msgtype for c in src.channels}
        assert {c.topic: c.msgtype for c in dst.channels if c.topic in types} == types
        assert {c.topic: c.message_count for c in dst.channels if c.topic in types} == {
            topic: len(messages) for topic, messages in given.items()
        }
    (tmp_path / "again").mkdir()
    again = log_path(tmp_path / "again", kind, "out")  # the same name: a bag folder's files hold it
    assert main(["process", str(log.path), "-o", str(again), "-q"]) == 0
    assert tree_bytes(again) == tree_bytes(out)


@pytest.mark.parametrize(
    ("kind", "fmt"), [("mcap-ros2", "db3"), ("mcap-ros2", "mcap-dir"), ("db3", "mcap")]
)
def test_hundreds_of_topics_converted_keep_their_types_definitions_and_hashes(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]], kind: str, fmt: str
) -> None:
    """Converted to another format, each of 300 topics keeps its messages and gets its type's
    definition and, in a ROS 2 bag, its RIHS01 hash (which readers check against the definition),
    worked out from the input's definition where it has none (a ROS 2 MCAP file's schemas)."""
    from rosbags.typesys import Stores, get_typestore

    log = build_log(
        log_path(tmp_path, kind),
        kind,
        session_maps(fr079[:1]),
        scans_per_map=1,
        small_topics=TOPICS,
    )
    out = tmp_path / ("out.mcap" if fmt == "mcap" else "out")
    assert main(["process", str(log.path), "-o", str(out), "--format", fmt, "-q"]) == 0
    given, got = read_all(log.path), read_all(out)
    assert {topic: got.get(topic) for topic in given} == given
    store = get_typestore(Stores.ROS2_HUMBLE)
    with LogReader(out) as reader:
        channels = [c for c in reader.channels if c.topic in given]
    assert len(channels) == TOPICS + 2
    for channel in channels:
        if fmt != "mcap":  # an MCAP file's channels hold no hash
            assert channel.digest == store.hash_rihs01(channel.msgtype), channel.topic
        assert channel.msgdef, channel.topic
