"""Round trip per format: every input message copied unchanged, derived topics right, cleaned == ROSE."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from conftest import (
    FORMATS,
    START_NS,
    MapMsg,
    build_log,
    log_path,
    read_all,
    session_maps,
    tree_bytes,
)

import rose
from rose_logs.reader import LogReader
from rose_logs.session import process_log
from rose_logs.snapshots import decode_map
from rose_logs.storage.rosbags import Ros1WriteBackend
from rose_logs.storage.typesys import MAP_TYPE, typestore_for


@pytest.mark.parametrize("kind", list(FORMATS))
def test_round_trip_copies_everything_and_adds_derived_topics(
    tmp_path: Path, kind: str, fr079
) -> None:
    built = build_log(log_path(tmp_path, kind), kind, session_maps(fr079))
    before = tree_bytes(built.path)
    out = log_path(tmp_path, kind, "out")
    report = process_log(built.path, output_path=out)

    assert tree_bytes(built.path) == before  # input untouched
    with LogReader(out) as reader:
        assert reader.format == built.fmt
        assert reader.serialization == built.serialization
    inp, got = read_all(built.path), read_all(out)
    for topic, messages in inp.items():
        assert got[topic] == messages  # same count, times and bytes, in order
    assert set(got) == set(inp) | {
        "/map/rose/cleaned",
        "/map/rose/structure_score",
        "/map/rose/walls",
    }

    store = typestore_for(built.serialization)
    deser = store.deserialize_ros1 if built.serialization == "ros1" else store.deserialize_cdr
    assert len(report.records) == len(fr079) == len(got["/map/rose/cleaned"])
    for grid, (t_map, raw_map), (t_clean, raw_clean), (t_w, raw_w), (_, raw_walls) in zip(
        fr079,
        got["/map"],
        got["/map/rose/cleaned"],
        got["/map/rose/structure_score"],
        got["/map/rose/walls"],
        strict=True,
    ):
        assert t_map == t_clean == t_w
        expected = rose.analyze(grid)
        source = deser(raw_map, MAP_TYPE)
        cleaned = deser(raw_clean, MAP_TYPE)
        assert cleaned.header == source.header
        assert cleaned.info == source.info
        np.testing.assert_array_equal(
            np.asarray(cleaned.data).reshape(grid.shape),
            rose.clean(grid, expected, resolution_m=0.05).cleaned,
        )
        score = deser(raw_w, "std_msgs/msg/Float32").data
        np.testing.assert_allclose(score, expected.structure_score, rtol=1e-6)
        walls = deser(raw_walls, "visualization_msgs/msg/MarkerArray")
        assert [m.type for m in walls.markers] == [5, 9]
        assert len(walls.markers[0].points) == 2 * expected.dominant_directions.size
        assert walls.markers[0].header.frame_id == "map"


def test_ros1_output_holds_only_the_filling_chunks_index_entries(tmp_path: Path, fr079) -> None:
    """rosbags kept every message's index entry (time, place) of every chunk written until the
    bag closed, memory growing with the session's messages (150 MB at 1.2 million); only the
    counts of the chunks written are needed, for the chunk infos at the end."""
    built = build_log(
        log_path(tmp_path, "ros1"), "ros1", session_maps(fr079[:2]), scans_per_map=300
    )
    out = tmp_path / "out.bag"
    backend = Ros1WriteBackend(out)
    backend.open()
    backend.writer.chunk_threshold = 64 * 1024  # many chunks of a small log
    held = 0
    with LogReader(built.path) as reader:
        handles = {channel.id: backend.add(channel) for channel in reader.channels}
        for m in reader.messages():
            backend.write(handles[m.channel.id], m.log_time_ns, m.data, m.publish_time_ns, 0)
            entries = [e for c in backend.writer.chunks for e in c.connections.values()]
            held = max(held, sum(len(e) for e in entries if isinstance(e, list)))
        written, count = len(backend.writer.chunks) - 1, reader.message_count
        backend.close()
    assert written >= 3
    assert held < count / 2  # the filling chunk's, not the bag's
    assert read_all(out) == read_all(built.path)  # rosbags reads the index back, counts checked
    with LogReader(out) as copy:
        assert copy.message_count == count


@pytest.mark.parametrize("kind", ["ros1", "db3", "mcap-ros2", "mcap-ros1"])
def test_connection_metadata_is_kept(tmp_path: Path, kind: str, fr079) -> None:
    built = build_log(log_path(tmp_path, kind), kind, session_maps(fr079[:1]))
    out = log_path(tmp_path, kind, "out")
    process_log(built.path, output_path=out)
    with LogReader(built.path) as a, LogReader(out) as b:
        before = {c.topic: c for c in a.channels}
        after = {c.topic: c for c in b.channels}
    for topic, c in before.items():
        d = after[topic]
        assert (d.msgtype, d.message_encoding, d.msgdef, d.digest) == (
            c.msgtype,
            c.message_encoding,
            c.msgdef,
            c.digest,
        )
        assert (d.callerid, d.latching) == (c.callerid, c.latching)
        assert d.offered_qos_profiles == c.offered_qos_profiles
        added = {k: v for k, v in d.metadata.items() if k not in c.metadata}
        assert {k: d.metadata[k] for k in c.metadata} == dict(c.metadata)  # kept as is
        # ... and the ros2 profile's required offered_qos_profiles added where the input lacked it
        if c.message_encoding == "cdr" and kind.startswith("mcap"):
            assert set(added) <= {"offered_qos_profiles"}
            assert "offered_qos_profiles" in d.metadata
        else:
            assert added == {}
    cleaned = after["/map/rose/cleaned"]
    assert (
        bool(cleaned.latching)
        or any(q.durability.name == "TRANSIENT_LOCAL" for q in cleaned.offered_qos_profiles)
        or "transient_local" in cleaned.metadata.get("offered_qos_profiles", "")
    )


def test_mcap_publish_time_and_sequence_kept(tmp_path: Path, fr079) -> None:
    from mcap.reader import make_reader

    built = build_log(log_path(tmp_path, "mcap-ros2"), "mcap-ros2", session_maps(fr079[:2]))
    out = tmp_path / "out.mcap"
    process_log(built.path, output_path=out)

    def stamps(path: Path, skip: str = "/rose/") -> list[tuple[str, int, int, int]]:
        with path.open("rb") as f:
            return [
                (c.topic, m.log_time, m.publish_time, m.sequence)
                for _, c, m in make_reader(f).iter_messages(log_time_order=True)
                if skip not in c.topic
            ]

    assert stamps(out) == stamps(built.path)


@pytest.mark.parametrize("kind", ["ros1", "db3", "mcap-ros2"])
def test_output_is_deterministic(tmp_path: Path, kind: str, fr079) -> None:
    built = build_log(log_path(tmp_path, kind), kind, session_maps(fr079[:2]))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first, second = log_path(tmp_path / "a", kind, "out"), log_path(tmp_path / "b", kind, "out")
    process_log(built.path, output_path=first)
    process_log(built.path, output_path=second)
    assert tree_bytes(first) == tree_bytes(second)


@pytest.mark.parametrize("kind", ["ros1", "mcap-ros2"])
def test_output_does_not_depend_on_analysis_timing(
    tmp_path: Path, kind: str, fr079, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Analyses run ahead in threads; however long each takes, messages and results are written in
    log order, so the output is the same bytes."""
    import random
    import time

    from rose_logs.session.analysis import SnapshotAnalyser

    grids = [*fr079, fr079[0], fr079[2]]  # five snapshots; none equal to the one before it
    built = build_log(log_path(tmp_path, kind), kind, session_maps(grids), scans_per_map=6)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    steady, jittered = log_path(tmp_path / "a", kind, "out"), log_path(tmp_path / "b", kind, "out")
    process_log(built.path, output_path=steady)
    analyse = SnapshotAnalyser.analyse
    delays = random.Random(7)

    def slow(self: SnapshotAnalyser, snapshot):  # type: ignore[no-untyped-def]
        time.sleep(delays.choice([0.0, 0.05, 0.2]))  # later snapshots may finish first
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "analyse", slow)
    report = process_log(built.path, output_path=jittered)
    assert [r.index for r in report.records] == list(range(5))
    assert tree_bytes(steady) == tree_bytes(jittered)


def test_a_ros1_bag_written_topic_after_topic_reads_each_chunk_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Its chunks overlap in time (a merge script's bag): rosbags, reading through every
    message's index entry with one chunk decompressed, decompressed a chunk again at nearly
    every message (bz2: 275 s for 10,000 messages, 3 s read once). The order is rosbags'."""
    from rosbags.rosbag1 import Writer
    from rosbags.rosbag1 import reader as rosbags_reader
    from rosbags.typesys import Stores, get_typestore

    from rose_logs.storage import ros1_stream

    store = get_typestore(Stores.ROS1_NOETIC)
    string = store.types["std_msgs/msg/String"]
    path = tmp_path / "merged.bag"
    writer = Writer(path)
    writer.set_compression(Writer.CompressionFormat.BZ2)
    writer.chunk_threshold = 4096  # bytes: several chunks per topic
    with writer:
        for k, topic in enumerate(("/a", "/b")):
            conn = writer.add_connection(topic, "std_msgs/msg/String", typestore=store)
            for i in range(300):
                data = store.serialize_ros1(string(data=f"{topic} {i:050d}"), "std_msgs/msg/String")
                writer.write(conn, START_NS + 1000 * i + k, data)
    decompressed = 0

    def counted(decompress):  # type: ignore[no-untyped-def]
        def call(*args, **kwargs):  # type: ignore[no-untyped-def]
            nonlocal decompressed
            decompressed += 1
            return decompress(*args, **kwargs)

        return call

    monkeypatch.setitem(rosbags_reader.decompressors, "bz2", counted(rosbags_reader.bz2_decompress))
    monkeypatch.setattr(ros1_stream, "_decompress", counted(ros1_stream._decompress))
    with LogReader(path) as reader:
        got = [(m.channel.topic, m.log_time_ns) for m in reader.messages()]
    chunks = len(ros1_stream.read_index(path).chunks)
    assert chunks >= 6
    assert decompressed <= chunks
    topics = ("/a", "/b")
    assert got == [(t, START_NS + 1000 * i + k) for i in range(300) for k, t in enumerate(topics)]


def _topic_after_topic_bag(path: Path, texts: int, text: str, *, bz2: bool) -> None:
    """A ROS 1 bag as a merge script writes it: ``texts`` strings ``text`` on ``/a`` (1000 ns
    apart), then as many on ``/b`` (1 ns after each), two per chunk of 4 kB (``text`` of 3000
    bytes): its chunks overlap in time."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    string = store.types["std_msgs/msg/String"]
    writer = Writer(path)
    if bz2:
        writer.set_compression(Writer.CompressionFormat.BZ2)
    writer.chunk_threshold = 4096
    with writer:
        for k, topic in enumerate(("/a", "/b")):
            conn = writer.add_connection(topic, "std_msgs/msg/String", typestore=store)
            for i in range(texts):
                data = store.serialize_ros1(string(data=text), "std_msgs/msg/String")
                writer.write(conn, START_NS + 1000 * i + k, data)


def test_overlapping_ros1_chunks_are_bounded_by_their_decompressed_bytes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The chunks held at once to read each once are counted decompressed, as they are held:
    bz2 chunks of zeros store a hundredth of their bytes, and counted stored they passed a bound
    their messages exceeded many times over (rosbags' reading, in constant memory, beyond)."""
    from rose_logs.storage import rosbags as rosbags_storage

    path = tmp_path / "merged.bag"
    _topic_after_topic_bag(path, 20, "0" * 3000, bz2=True)
    monkeypatch.setattr(rosbags_storage, "MAX_OVERLAP_BYTES", 5000)  # not one chunk read
    backend = rosbags_storage.RosbagsReadBackend(path, "ros1")
    backend.open()
    try:
        assert sum(c.datasize for c in backend.reader.chunks.values()) < 5000  # 6 kB each, read
        assert backend._ros1_index_if_chunks_overlap(None) is None  # rosbags' reading
        monkeypatch.setattr(rosbags_storage, "MAX_OVERLAP_BYTES", 50_000)  # a few chunks
        assert backend._ros1_index_if_chunks_overlap(None) is not None
    finally:
        backend.close()


def test_overlapping_ros1_chunks_with_a_damaged_message_time_are_refused(tmp_path: Path) -> None:
    """A message whose time no longer matches its index entry (a flipped byte) is the damage
    rosbags refuses ("the bag's index is damaged"), read chunk by chunk too: that reading took
    the message's own time, handing it out at another time and place, silently."""
    from rose_logs.errors import LogReadError

    path = tmp_path / "merged.bag"
    _topic_after_topic_bag(path, 6, "x" * 3000, bz2=False)
    data = bytearray(path.read_bytes())
    # The time of a message of /b in its record header (sec, nsec): nsec's low byte.
    at = data.index(b"time=", data.index(b"x" * 3000, data.index(b"topic=/b"))) + len(b"time=") + 4
    data[at] ^= 0x10
    path.write_bytes(data)
    with LogReader(path) as reader, pytest.raises(LogReadError, match="index is damaged"):
        list(reader.messages())


def test_overlapping_ros1_chunks_with_a_damaged_chunk_info_time_read_in_rosbags_order(
    tmp_path: Path,
) -> None:
    """A chunk info whose start time is later than its chunk's messages (a flipped byte in the
    index; rosbags orders by the messages' index entries alone and reads the bag as it was): read
    chunk by chunk, that chunk was read at its info's time, its messages handed out late, out of
    log-time order, silently. Such a bag is read as rosbags reads it."""
    import struct

    from rosbags.rosbag1 import Reader

    from rose_logs.storage.ros1_stream import read_index

    path = tmp_path / "merged.bag"
    _topic_after_topic_bag(path, 6, "x" * 3000, bz2=False)
    index = read_index(path)
    data = bytearray(path.read_bytes())
    # The start time of the last chunk info (one of /b's): 1.5 us later, past /a's next message.
    at = data.rindex(b"start_time=", index.index_pos) + len(b"start_time=") + 4
    struct.pack_into("<I", data, at, struct.unpack_from("<I", data, at)[0] + 1500)
    path.write_bytes(data)
    with Reader(path) as reader:
        expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    with LogReader(path) as ours:
        got = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in ours.messages()]
    assert got == expected
    assert [t for _, t, _ in got] == sorted(t for _, t, _ in got)


def _strings_bag(
    path: Path,
    times: list[int],
    topics: list[int],
    *,
    compression: str = "",
    chunk_threshold: int = 4096,
) -> None:
    """A ROS 1 bag of short strings, the ``i``-th on ``/t<topics[i]>`` at ``START_NS +
    times[i]``, written in that order in chunks of ``chunk_threshold`` bytes (``compression``:
    ``BZ2``, ``LZ4``, none)."""
    from rosbags.rosbag1 import Writer

    writer = Writer(path)
    if compression:
        writer.set_compression(getattr(Writer.CompressionFormat, compression))
    writer.chunk_threshold = chunk_threshold
    with writer:
        conns = {
            k: writer.add_connection(f"/t{k}", "std_msgs/msg/String", msgdef="string data", md5sum="992ce8a1687cec8c8bd883ec73ca41d1")
            for k in sorted(set(topics))
        }  # fmt: skip
        for i, (time, topic) in enumerate(zip(times, topics, strict=True)):
            text = f"{i}".encode()
            writer.write(conns[topic], START_NS + time, len(text).to_bytes(4, "little") + text)


def test_ros1_reading_holds_the_index_entries_of_the_chunks_being_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """rosbags' reader read every message's index entry when it opened a bag and held them all
    (about 175 bytes a message: 254 MB for `info` of 1.2 million messages); each chunk's are
    now read when its messages are, and dropped once handed out: memory does not grow with the
    bag."""
    import tracemalloc
    import weakref

    from rose_logs.storage.ros1_stream import read_index

    n = 20_000
    path = tmp_path / "many.bag"
    _strings_bag(path, list(range(n)), [i % 3 for i in range(n)], chunk_threshold=16 * 1024)
    with LogReader(path) as reader:  # (what a first reading imports is not counted)
        next(iter(reader.messages()))
    tracemalloc.start()
    try:
        with LogReader(path) as reader:
            opened = tracemalloc.get_traced_memory()[0]
            counts = [channel.message_count for channel in reader.channels]
    finally:
        tracemalloc.stop()
    assert counts == [n // 3 + (k < n % 3) for k in range(3)]
    assert opened < 512 * 1024  # rosbags held 3 MB of index entries here

    from rose_logs.storage.ros1_index import LazyIndexReader

    class Entries(list):  # type: ignore[type-arg]  # (a list that can be watched)
        __hash__ = object.__hash__

    alive: weakref.WeakSet[Entries] = weakref.WeakSet()
    read_entries = LazyIndexReader._read_entries

    def watched(self: LazyIndexReader, notes: object, row: int) -> Entries:
        entries = Entries(read_entries(self, notes, row))  # type: ignore[arg-type]
        alive.add(entries)
        return entries

    monkeypatch.setattr(LazyIndexReader, "_read_entries", watched)
    held = read = 0
    with LogReader(path) as reader:
        for _ in reader.messages():
            held = max(held, sum(len(entries) for entries in alive))
            read += 1
    assert read == n
    assert len(read_index(path).chunks) >= 20
    assert 0 < held < n / 5  # a chunk's of each topic, about: not the bag's


def test_ros1_reading_holds_less_than_rosbags_where_chunks_hold_few_messages_of_each_topic(
    tmp_path: Path,
) -> None:
    """What is noted per connection and chunk (where its index data is, its count and time span)
    took about 330 bytes (an object, a list, a dict entry keyed by a tuple): where a chunk holds
    one message of each of many topics (a recording of many slow topics, or of large messages
    between them), more than rosbags' one entry a message (chunk infos and chunks alike: 33
    against 18 MB for 100,000 messages on 20 topics). Now five numbers in arrays: less."""
    import tracemalloc

    from rosbags.rosbag1 import Reader

    from rose_logs.storage.ros1_index import LazyIndexReader

    n, topics = 4000, 20
    path = tmp_path / "few.bag"
    # Each chunk closes after a message of each topic: about 60 bytes a message record.
    _strings_bag(path, list(range(n)), [i % topics for i in range(n)], chunk_threshold=topics * 55)
    held = {}
    for kind in (Reader, LazyIndexReader):
        tracemalloc.start()
        try:
            with kind(path) as reader:
                held[kind] = tracemalloc.get_traced_memory()[0]
                counts = [conn.msgcount for conn in reader.connections]
                chunks = len(reader.chunk_infos)
        finally:
            tracemalloc.stop()
        assert counts == [n // topics] * topics
    assert chunks >= n / topics / 2  # a message or two of each topic a chunk
    assert held[LazyIndexReader] < 0.8 * held[Reader]


def test_ros1_chunks_overlapping_at_their_ends_are_merged_a_run_at_a_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A topic whose chunks overlap in time only at their ends (stamps a little out of order, as
    a recording stamped by its messages' headers has them), read in rosbags' order (its chunks
    overlapping would hold more than MAX_OVERLAP_BYTES at once, here 0), was merged entry by
    entry through a heap in Python: 1.2 million such messages read in 6.3 s of CPU, rosbags'
    reader in 5.5 s. Each chunk's entries now go out in runs, up to the first that another
    chunk's precedes: a few heap steps a chunk. Same messages in rosbags' order (ties at the
    ends included)."""
    import heapq

    from rosbags.rosbag1 import Reader

    from rose_logs.storage import ros1_index
    from rose_logs.storage import rosbags as rosbags_storage

    monkeypatch.setattr(rosbags_storage, "MAX_OVERLAP_BYTES", 0)

    n = 3000
    path = tmp_path / "jitter.bag"
    times = [3 * i + 7 * (i % 5) for i in range(n)]  # each 5 messages a little out of order
    _strings_bag(path, times, [0] * n, chunk_threshold=2048)
    with Reader(path) as reader:
        infos = sorted(reader.chunk_infos, key=lambda info: info.start_time)
        expected = [(t, bytes(d)) for _, t, d in reader.messages()]
    assert len(infos) > 20
    assert all(a.end_time > b.start_time for a, b in itertools.pairwise(infos))  # overlap

    steps = 0

    class Counted:  # heapq, its steps counted
        def __getattr__(self, name: str) -> object:
            def step(*args: object) -> object:
                nonlocal steps
                steps += 1
                return getattr(heapq, name)(*args)

            return step

    monkeypatch.setattr(ros1_index, "heapq", Counted())
    with LogReader(path) as ours:
        got = [(m.log_time_ns, bytes(m.data)) for m in ours.messages()]
    assert got == expected
    assert steps < n / 5  # were about n (one an entry)


def test_ros1_index_data_is_read_again_in_one_go_and_a_changed_record_through_rosbags(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """rosbags reads an index data record an entry at a time (three calls a message): where a
    chunk holds a message or two of each of many topics, reading each again while reading the
    messages took most of what the lazy index added (300,000 messages on 200 topics: 2.7 s of
    CPU, rosbags' reader 1.7). A record as open() noted it (rosbags' code read and checked it
    then) is now unpacked in one go; one that changed since goes through rosbags' code, for its
    error."""
    import struct

    from rosbags.rosbag1 import Reader

    from rose_logs.storage.ros1_index import LazyIndexReader

    n, topics = 600, 30
    path = tmp_path / "many.bag"
    _strings_bag(path, [i // 7 for i in range(n)], [i % topics for i in range(n)], chunk_threshold=topics * 60)  # fmt: skip
    with Reader(path) as reader:
        expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    calls = 0
    read_index_data = Reader.read_index_data

    def counted(self: Reader, pos: int, indexes: dict[int, list[object]]) -> None:
        nonlocal calls
        calls += 1
        read_index_data(self, pos, indexes)  # type: ignore[arg-type]

    monkeypatch.setattr(Reader, "read_index_data", counted)
    with LazyIndexReader(path) as reader:
        calls = 0
        got = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        assert calls == 0
        # A count changed under the reader: rosbags' check of it fails, as rosbags' reading did.
        notes = reader._notes[reader.connections[0].id]
        with path.open("r+b") as bag:
            bag.seek(notes.at[-1] + reader.index_data_header_offsets[1])  # type: ignore[index]
            bag.write(struct.pack("<I", notes.count[-1] + 1))
        with pytest.raises(AssertionError):
            list(reader.messages())
        assert calls > 0
    assert got == expected


def test_ros1_open_notes_each_index_data_record_as_rosbags_reads_it(tmp_path: Path) -> None:
    """The lazy index notes most index data records from their bytes (rosbags' code reads the
    first, for its layout, and any that fails its checks, for its error): the same counts, time
    spans, messages and errors as rosbags' reader, on a bag of many topics in small chunks (a
    message or two of each per chunk) and with a record's count or length damaged."""
    import struct

    from rosbags.rosbag1 import Reader

    from rose_logs.storage.ros1_index import LazyIndexReader

    n, topics = 600, 30
    path = tmp_path / "many.bag"
    _strings_bag(path, [(i * 7919) % 50 + i // 3 for i in range(n)], [i % topics for i in range(n)], chunk_threshold=topics * 60)  # fmt: skip
    with Reader(path) as reader:
        expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        counts = [c.msgcount for c in reader.connections]
        spans = {
            pos: (min(e.time for e in entries), max(e.time for e in entries))
            for pos in {e.chunk_pos for listed in reader.indexes.values() for e in listed}
            for entries in [[e for lst in reader.indexes.values() for e in lst if e.chunk_pos == pos]]
        }  # fmt: skip
    with LazyIndexReader(path) as reader:
        assert [c.msgcount for c in reader.connections] == counts
        assert reader.entry_spans({c.id for c in reader.connections}) == spans
        assert [(c.topic, t, bytes(d)) for c, t, d in reader.messages()] == expected
        notes = reader._notes[reader.connections[3].id]
        at = notes.at[len(notes.at) // 2]
        count_at = at + reader.index_data_header_offsets[1]  # type: ignore[index]
        count = notes.count[len(notes.at) // 2]
    intact = path.read_bytes()
    # A record's count that its length does not fit; one whose length reaches past the file's
    # end: rosbags' errors, as rosbags' reader gives them.
    for changed, size in ((count + 1, 12 * count), (10**6, 12 * 10**6)):
        with path.open("r+b") as bag:
            bag.seek(count_at)
            bag.write(struct.pack("<I", changed))
            bag.seek(at + 51)  # the record's data length, after its header
            bag.write(struct.pack("<I", size))
        raised = []
        for kind in (Reader, LazyIndexReader):
            with pytest.raises(Exception) as err:
                kind(path).open()
            raised.append((type(err.value), str(err.value)))
        assert raised[0] == raised[1]
        path.write_bytes(intact)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("overlap_bytes", [None, 0])
def test_ros1_messages_come_in_rosbags_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int, overlap_bytes: int | None
) -> None:
    """The index entries read chunk by chunk give the messages rosbags' reader gives (holding
    them all), in its order: log time, then the connection's place, the chunk info's, the
    entry's. Times repeat across topics and chunks, chunks overlap (written out of order; read
    each once, or with ``overlap_bytes`` 0 through the entries as rosbags does), topic subsets."""
    from rosbags.rosbag1 import Reader

    from rose_logs.storage import rosbags as rosbags_storage

    if overlap_bytes is not None:
        monkeypatch.setattr(rosbags_storage, "MAX_OVERLAP_BYTES", overlap_bytes)
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 600))
    times = np.cumsum(rng.integers(0, 3, n)) if seed % 2 else rng.integers(0, 80, n)
    path = tmp_path / "random.bag"
    compression = ["", "BZ2", "LZ4"][seed % 3]
    threshold = int(rng.integers(200, 3000))
    _strings_bag(path, [int(t) for t in times], rng.integers(0, 4, n).tolist(), compression=compression, chunk_threshold=threshold)  # fmt: skip
    for topics in (None, {"/t0"}, {"/t1", "/t3"}):
        with Reader(path) as reader:
            conns = [c for c in reader.connections if topics is None or c.topic in topics]
            expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages(conns)]
            counts = {c.topic: c.msgcount for c in reader.connections}
        with LogReader(path) as ours:
            got = [
                (m.channel.topic, m.log_time_ns, bytes(m.data))
                for m in ours.messages(topics=topics)
            ]
            assert {c.topic: c.message_count for c in ours.channels} == counts
        assert got == expected


def test_messages_held_behind_a_slow_analysis_are_bounded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Messages read while a map is analysed wait in memory to be written after its results; past
    a bound the reading waits for the analysis (a camera's images behind a large map were all held).
    Here the analysis finishes only when the session waits for it; the output is the same bytes."""
    import threading

    from synthetic import ros_floor_plan

    import rose_logs.session.loop as loop
    from rose_logs.session.analysis import SnapshotAnalyser

    maps = session_maps([ros_floor_plan((120, 160))])
    built = build_log(log_path(tmp_path, "mcap-ros2"), "mcap-ros2", maps, scans_per_map=40)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    unbounded, bounded = tmp_path / "a" / "out.mcap", tmp_path / "b" / "out.mcap"
    process_log(built.path, output_path=unbounded)

    cap = 4000  # bytes: about five scans
    monkeypatch.setattr(loop, "_MAX_HELD_BYTES", cap)
    waited_for = threading.Event()
    analyse, finish, step = SnapshotAnalyser.analyse, loop._Loop._finish, loop._Loop._step
    held: list[int] = []

    def when_waited_for(self, snapshot):  # type: ignore[no-untyped-def]
        assert waited_for.wait(30), "the session never waited for the analysis"
        return analyse(self, snapshot)

    def waits(self, pending):  # type: ignore[no-untyped-def]
        waited_for.set()
        return finish(self, pending)

    def reads(self, message):  # type: ignore[no-untyped-def]
        step(self, message)
        held.append(sum(len(i.data) for i in self.queue if isinstance(i, loop._Copy)))

    monkeypatch.setattr(SnapshotAnalyser, "analyse", when_waited_for)
    monkeypatch.setattr(loop._Loop, "_finish", waits)
    monkeypatch.setattr(loop._Loop, "_step", reads)
    process_log(built.path, output_path=bounded)
    largest = max(len(data) for _, data in read_all(built.path)["/scan"])
    assert 0 < max(held) <= cap + largest  # unbounded: all 40 scans (31 kB)
    assert tree_bytes(unbounded) == tree_bytes(bounded)


@pytest.mark.parametrize(
    ("src", "fmt", "suffix"),
    [("mcap-ros2", "db3", ""), ("db3", "mcap", ".mcap"), ("ros1", "mcap", ".mcap")],
)
def test_format_conversion_keeps_messages(
    tmp_path: Path, src: str, fmt: str, suffix: str, fr079
) -> None:
    built = build_log(log_path(tmp_path, src), src, session_maps(fr079[:1]))
    out = tmp_path / f"out{suffix}"
    process_log(built.path, output_path=out, output_format=fmt)
    inp, got = read_all(built.path), read_all(out)
    for topic, messages in inp.items():
        assert got[topic] == messages


def test_grid_updates_are_applied_to_the_last_full_map(tmp_path: Path, fr079) -> None:
    base = fr079[0]
    patch = fr079[2][50:150, 100:300]
    maps = [
        MapMsg(START_NS + 1_000_000_000, base),
        MapMsg(START_NS + 2_000_000_000, patch, topic="/map_updates", xy=(100, 50)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    out = tmp_path / "out.mcap"
    report = process_log(built.path, output_path=out)
    assert [r.from_update for r in report.records] == [False, True]
    patched = base.copy()
    patched[50:150, 100:300] = patch
    cleaned = read_all(out)["/map/rose/cleaned"]
    assert [t for t, _ in cleaned] == [START_NS + 1_000_000_000, START_NS + 2_000_000_000]
    snap = decode_map(cleaned[1][1], serialization="cdr", topic="/x", log_time_ns=0)
    np.testing.assert_array_equal(snap.grid, rose.clean(patched, resolution_m=0.05).cleaned)


def test_unchanged_grid_reuses_result_and_metadata_changes_are_followed(
    tmp_path: Path, fr079
) -> None:
    g = fr079[1]
    maps = [
        MapMsg(START_NS + 1_000_000_000, g),
        MapMsg(START_NS + 2_000_000_000, g),
        MapMsg(
            START_NS + 3_000_000_000,
            g[:200, :500].copy(),
            resolution_m=0.1,
            origin_xy_m=(3.0, -2.0),
        ),
    ]
    built = build_log(tmp_path / "in.bag", "ros1", maps)
    report = process_log(built.path, output_path=tmp_path / "out.bag")
    assert [r.reused for r in report.records] == [False, True, False]
    assert [(r.height, r.width) for r in report.records] == [g.shape, g.shape, (200, 500)]
    np.testing.assert_allclose(
        [r.resolution_m for r in report.records], [0.05, 0.05, 0.1], rtol=1e-6
    )
    cleaned = read_all(tmp_path / "out.bag")["/map/rose/cleaned"]
    last = decode_map(cleaned[2][1], serialization="ros1", topic="/x", log_time_ns=0)
    assert last.shape == (200, 500)
    assert last.origin_position_m[:2] == (3.0, -2.0)
    np.testing.assert_array_equal(last.grid, rose.clean(g[:200, :500], resolution_m=0.1).cleaned)


def test_break_is_reported_at_the_first_distorted_snapshot(
    tmp_path: Path, fr079, broken_grid
) -> None:
    grids = [*fr079, broken_grid, broken_grid]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(grids))
    report = process_log(built.path, output_path=None)
    scores = [r.structure_score for r in report.records]
    assert max(scores[:3]) < 0.4 < scores[3]
    first = report.first_w_above("/map")
    assert first is not None
    assert first.index == 3
    assert first.log_time_ns == START_NS + 20_000_000_000
    assert len(report.breaks) == 1  # staying broken is not a new break
    detected = report.first_break("/map")  # the break detector agrees on this one
    assert detected is not None
    assert (detected.index, detected.trusted_index) == (3, 2)
    assert len(report.detected_breaks) == 1
    assert [r.break_score_m >= report.break_threshold_m for r in report.records] == [
        False,
        False,
        False,
        True,
        True,
    ]
    assert report.records[4].reused


@pytest.mark.parametrize(("picked", "other"), [("/map", "/robot2/map"), ("/robot2/map", "/map")])
def test_picking_one_map_never_applies_another_maps_updates(
    tmp_path: Path, fr079, picked: str, other: str
) -> None:
    """Two map topics, updates for one of them: ``--topic`` on the other must not receive them (a
    patch of another map erased walls and raised a false break)."""
    base = fr079[0]
    erase = np.zeros((100, 200), np.int8)  # free space over a stretch of the other map's walls
    maps = [
        MapMsg(START_NS + 1_000_000_000, base, topic="/map"),
        MapMsg(START_NS + 1_000_000_000, base, topic="/robot2/map"),
        MapMsg(START_NS + 2_000_000_000, erase, topic=f"{other}_updates", xy=(100, 50)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = process_log(built.path, output_path=None, topics=[picked])
    assert [(r.topic, r.from_update) for r in report.records] == [(picked, False)]
    assert report.skipped_messages == 0  # not "malformed": simply not this map's
    everything = process_log(built.path, output_path=None)
    assert [(r.topic, r.from_update) for r in everything.records] == [
        ("/map", False),
        ("/robot2/map", False),
        (other, True),
    ]


def test_updates_named_after_a_map_we_cannot_decode_go_to_no_other_map() -> None:
    """``/local_map_updates`` belongs to ``/local_map`` (JSON-encoded here, so not analysed), never to
    the log's one analysable map."""
    from rose_logs.session.topics import update_targets
    from rose_logs.storage.records import Channel
    from rose_logs.storage.typesys import UPDATE_TYPE

    channels = [
        Channel(0, "/map", MAP_TYPE, "cdr"),
        Channel(1, "/local_map", MAP_TYPE, "json"),
        Channel(2, "/local_map_updates", UPDATE_TYPE, "cdr"),
        Channel(3, "/map_updates", UPDATE_TYPE, "cdr"),
    ]
    assert update_targets(channels) == {"/map_updates": "/map"}
    # Without /local_map in the log its updates are still not /map's (another costmap's).
    assert update_targets(channels[:1] + channels[2:3]) == {}


def test_a_recording_rosbag_never_closed_is_named_like_a_bag_once_processed() -> None:
    from rose_logs.session import default_output_path

    assert default_output_path(Path("runs/k.bag.active")) == Path("runs/k.rose.bag")
    assert default_output_path(Path("runs/k.bag")) == Path("runs/k.rose.bag")
    assert default_output_path(Path("runs/k.bag.active"), "mcap") == Path("runs/k.rose.mcap")
    assert default_output_path(Path("runs/k.mcap"), "mcap-dir") == Path("runs/k.rose")


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_a_map_of_no_cells_is_empty_not_malformed(serialization: str) -> None:
    """A message of no cells (a default-constructed map, resolution 0 too) is valid: it reads as
    empty, which the session counts apart from malformed messages; cells declared without data
    are malformed still."""
    from rose_logs.errors import EmptyMapError, MapMessageError

    store = typestore_for(serialization)
    types = store.types
    grid_msg = types[MAP_TYPE]
    header = types["std_msgs/msg/Header"](
        **({"seq": 0} if serialization == "ros1" else {}),
        stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
        frame_id="",
    )
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=0.0),
    )

    def encoded(width: int, height: int) -> bytes:
        info = types["nav_msgs/msg/MapMetaData"](
            map_load_time=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
            resolution=0.0,
            width=width,
            height=height,
            origin=pose,
        )
        message = grid_msg(header=header, info=info, data=np.zeros(0, dtype=np.int8))
        if serialization == "ros1":
            return bytes(store.serialize_ros1(message, MAP_TYPE))
        return bytes(store.serialize_cdr(message, MAP_TYPE))

    with pytest.raises(EmptyMapError, match=r"/x: empty map \(0 x 0 cells\)"):
        decode_map(encoded(0, 0), serialization=serialization, topic="/x", log_time_ns=0)
    with pytest.raises(MapMessageError) as declared:
        decode_map(encoded(3, 2), serialization=serialization, topic="/x", log_time_ns=0)
    assert not isinstance(declared.value, EmptyMapError)
