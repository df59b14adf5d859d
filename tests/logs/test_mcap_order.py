"""Reading an MCAP file chunk by chunk gives the library's log-time order exactly."""

from __future__ import annotations

import dataclasses
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, IndexType, Writer

from rose_logs.storage.mcap import McapReadBackend


def _write(
    path: Path,
    times: list[int],
    channels: list[int],
    chunk_size: int,
    size: int = 4,
    **options: Any,
) -> None:
    """Messages of ``size`` bytes (their number first) at ``times`` on ``/t0`` .. ``/t2``;
    ``options``: the writer's (no chunks, no chunk index)."""
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=chunk_size, **options)
        writer.start(profile="", library="test")
        schema = writer.register_schema(name="raw", encoding="", data=b"")
        ids = [writer.register_channel(f"/t{c}", "raw", schema) for c in range(3)]
        for i, (t, c) in enumerate(zip(times, channels, strict=True)):
            data = i.to_bytes(4, "little").ljust(size, b"x")
            writer.add_message(ids[c], log_time=t, data=data, publish_time=t)
        writer.finish()


def _library_order(path: Path, topics: set[str] | None) -> list[tuple[str, int, bytes]]:
    with path.open("rb") as stream:
        reader = make_reader(stream)
        return [
            (ch.topic, m.log_time, bytes(m.data))
            for _s, ch, m in reader.iter_messages(topics=topics, log_time_order=True)
        ]


def _our_order(path: Path, topics: set[str] | None) -> tuple[list[tuple[str, int, bytes]], bool]:
    backend = McapReadBackend(path)
    backend.open()
    try:
        sequential = backend._chunks_in_sequence(backend._wanted(topics)) is not None
        got = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in backend.messages(topics)]
    finally:
        backend.close()
    return got, sequential


@pytest.mark.parametrize("seed", range(40))
def test_chunk_by_chunk_reads_the_librarys_order(tmp_path: Path, seed: int) -> None:
    """Recorder-like files (times rising, ties, messages a little out of order inside a chunk)
    and files whose chunks overlap in time, several chunk sizes and topic selections."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    kind = seed % 4
    if kind == 0:  # strictly rising
        times = np.cumsum(rng.integers(1, 5, n))
    elif kind == 1:  # rising with ties
        times = np.cumsum(rng.integers(0, 2, n))
    elif kind == 2:  # a little out of order (within a few messages)
        times = np.arange(n) * 10 + rng.integers(-25, 25, n)
    else:  # anything
        times = rng.integers(0, 50, n)
    channels = rng.integers(0, 3, n).tolist()
    path = tmp_path / "order.mcap"
    _write(path, [int(t) + 1000 for t in times], channels, chunk_size=int(rng.integers(40, 2000)))
    for topics in (None, {"/t0"}, {"/t1", "/t2"}):
        got, _ = _our_order(path, topics)
        assert got == _library_order(path, topics)


def test_recorder_like_files_take_the_chunk_by_chunk_path(tmp_path: Path) -> None:
    """So that the test above compares the new path, not the library with itself."""
    path = tmp_path / "rising.mcap"
    _write(path, list(range(1000, 1500)), [i % 3 for i in range(500)], chunk_size=200)
    got, sequential = _our_order(path, None)
    assert sequential
    assert [t for _topic, t, _data in got] == list(range(1000, 1500))
    path = tmp_path / "overlapping.mcap"
    _write(path, [1000 + (i * 7919) % 500 for i in range(500)], [0] * 500, chunk_size=200)
    assert not _our_order(path, None)[1]


@pytest.mark.parametrize("seed", range(30))
def test_chunk_indexes_with_wrong_times_still_read_in_the_librarys_order(
    tmp_path: Path, seed: int
) -> None:
    """Writers have written chunk indexes whose times do not bound their chunk: a start time that
    leaves out messages logged at time 0 (foxglove/mcap#924), an end time of 0. The library reads
    such files, and so must we, in its order (the chunk-by-chunk reading hands over to its merge
    at the first chunk its index does not bound)."""
    rng = np.random.default_rng(1000 + seed)
    n = int(rng.integers(20, 300))
    times = 1000 + np.arange(n) * 10 + rng.integers(0, 5, n)  # rising, as recorders write
    times[rng.choice(n, size=int(rng.integers(1, 4)), replace=False)] = 0  # logged at time 0
    path = tmp_path / "index.mcap"
    _write(path, [int(t) for t in times], rng.integers(0, 3, n).tolist(), chunk_size=200)
    backend = McapReadBackend(path)
    backend.open()
    try:
        indexes = backend.reader.get_summary().chunk_indexes
        for index in indexes:
            logged = [m.log_time for m in backend._read_chunk(index)]
            if 0 in logged and max(logged) > 0:  # the start time leaves time 0 out
                index.message_start_time = min(t for t in logged if t > 0)
            if rng.random() < 0.2:
                index.message_end_time = 0
        for topics in (None, {"/t1"}):
            library = [
                (ch.topic, m.log_time, bytes(m.data))
                for _s, ch, m in backend.reader.iter_messages(topics=topics, log_time_order=True)
            ]
            ours = [
                (m.channel.topic, m.log_time_ns, bytes(m.data)) for m in backend.messages(topics)
            ]
            assert ours == library
    finally:
        backend.close()


#: Files whose summary indexes no chunk: written without chunks (rosbag2's ``fastwrite``), or
#: chunked without a chunk index.
NO_CHUNK_INDEX = [{"use_chunking": False}, {"index_types": IndexType.NONE}]


@pytest.mark.parametrize("options", NO_CHUNK_INDEX, ids=["no-chunks", "no-chunk-index"])
@pytest.mark.parametrize("seed", range(8))
def test_files_without_a_chunk_index_read_in_the_librarys_order(
    tmp_path: Path, seed: int, options: dict[str, Any]
) -> None:
    """Read record by record, in the library's order: in file order when that is log-time
    order, sorted (stably) when not."""
    rng = np.random.default_rng(2000 + seed)
    n = int(rng.integers(1, 300))
    times = np.cumsum(rng.integers(0, 3, n)) if seed % 2 else rng.integers(0, 50, n)
    path = tmp_path / "flat.mcap"
    _write(path, [int(t) + 1000 for t in times], rng.integers(0, 3, n).tolist(), 200, **options)
    for topics in (None, {"/t0"}, {"/t1", "/t2"}):
        assert _our_order(path, topics)[0] == _library_order(path, topics)


@pytest.mark.parametrize("options", NO_CHUNK_INDEX, ids=["no-chunks", "no-chunk-index"])
def test_files_without_a_chunk_index_stream_in_constant_memory(
    tmp_path: Path, options: dict[str, Any]
) -> None:
    """Messages in log-time order are handed out as they are read: the library's reader sorted
    every message of such a file in memory before the first (a 560 MB file took 720 MB)."""
    path = tmp_path / "flat.mcap"
    n, size = 200, 100_000  # 20 MB
    _write(path, list(range(1000, 1000 + n)), [i % 3 for i in range(n)], 1 << 20, size, **options)
    backend = McapReadBackend(path)
    backend.open()
    tracemalloc.start()
    try:
        read = 0
        for message in backend.messages(None):
            assert int.from_bytes(bytes(message.data[:4]), "little") == read
            read += 1
            del message
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
        backend.close()
    assert read == n
    assert peak < 6 << 20  # a chunk of 1 MiB and its messages: not the file's 20 MB


@pytest.mark.parametrize("options", NO_CHUNK_INDEX, ids=["no-chunks", "no-chunk-index"])
def test_files_without_a_chunk_index_too_large_to_sort_are_still_read(
    tmp_path: Path, options: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Out of order and over the in-memory sort's bound, such a file (valid, its summary whole)
    is read by the library's reader, as before the record-by-record reading: not refused as a
    file without a summary is (which has nothing else to be read by)."""
    from rose_logs.storage import mcap

    monkeypatch.setattr(mcap, "MAX_SORTED_BYTES", 1000)
    path = tmp_path / "flat.mcap"
    n = 60
    _write(
        path, [1000 + (7 * i) % 13 for i in range(n)], [i % 3 for i in range(n)], 200, 50, **options
    )
    assert _our_order(path, None)[0] == _library_order(path, None)


@pytest.mark.parametrize("options", NO_CHUNK_INDEX, ids=["no-chunks", "no-chunk-index"])
def test_files_without_a_chunk_index_out_of_order_are_sorted_without_a_warning(
    tmp_path: Path, options: dict[str, Any], caplog: pytest.LogCaptureFixture
) -> None:
    """Such a file is valid (its summary whole): sorted in memory as the library's reader did,
    silently, not with the warning of a file without a summary ("messages not in log-time order,
    no index"), said again at every reading."""
    path = tmp_path / "flat.mcap"
    _write(path, [1005, 1003, 1009, 1001], [0, 1, 2, 0], 200, **options)
    assert [t for _, t, _ in _our_order(path, None)[0]] == [1001, 1003, 1005, 1009]
    assert not caplog.records


def _reading_threads() -> set[Any]:
    """The readers' threads alive (other tests' readers may still be ending theirs)."""
    import threading

    return {t for t in threading.enumerate() if t.name.startswith("rose-mcap-reader")}


def test_a_damaged_chunk_read_ahead_fails_in_its_turn(tmp_path: Path) -> None:
    """The next chunk is read while the caller works on one: a chunk that cannot be read is said
    when its turn comes, after every message before it, as when chunks were read in turn; the
    reading thread ends with the error."""
    before = _reading_threads()
    path = tmp_path / "damaged.mcap"
    _write(path, list(range(1000, 1300)), [i % 3 for i in range(300)], chunk_size=200, size=64)
    backend = McapReadBackend(path)
    backend.open()
    indexes = backend.reader.get_summary().chunk_indexes
    earlier = sum(len(backend._read_chunk(index)) for index in indexes[:5])
    backend.close()
    data = bytearray(path.read_bytes())
    # The sixth chunk's uncompressed CRC (after its opcode, length, times and size).
    data[indexes[5].chunk_start_offset + 1 + 8 + 8 + 8 + 8] ^= 0xFF
    path.write_bytes(bytes(data))
    backend = McapReadBackend(path)
    backend.open()
    read = []
    try:
        with pytest.raises(Exception, match=r"(?i)crc"):  # the library's own error type
            for message in backend.messages(None):
                read.append(message.log_time_ns)
    finally:
        backend.close()
    assert read == list(range(1000, 1000 + earlier))
    assert _reading_threads() <= before


@pytest.mark.parametrize(
    "compression", [CompressionType.ZSTD, CompressionType.LZ4, CompressionType.NONE]
)
def test_a_chunk_reads_as_the_library_reads_it_and_a_wrong_crc_fails(
    tmp_path: Path, compression: CompressionType
) -> None:
    """Our chunk reading (zstd chunks checked with ISA-L's CRC-32) gives the library's records
    for every compression, and fails on a chunk whose data is intact but whose CRC is not."""
    from mcap.stream_reader import CRCValidationError, breakup_chunk

    from rose_logs.storage.mcap import _chunk_records

    path = tmp_path / "chunks.mcap"
    _write(path, list(range(1000, 1100)), [i % 3 for i in range(100)], 300, compression=compression)
    with path.open("rb") as stream:
        chunks = [r for r in StreamReader(stream, emit_chunks=True).records if isinstance(r, Chunk)]
    assert len(chunks) > 3
    for chunk in chunks:
        assert chunk.uncompressed_crc != 0
        assert _chunk_records(chunk) == breakup_chunk(chunk, validate_crc=True)
        wrong = dataclasses.replace(chunk, uncompressed_crc=chunk.uncompressed_crc ^ 1)
        with pytest.raises(CRCValidationError):
            _chunk_records(wrong)
        unchecked = dataclasses.replace(chunk, uncompressed_crc=0)  # 0: no CRC written
        assert _chunk_records(unchecked) == breakup_chunk(chunk)


def test_the_reading_thread_ends_when_the_reader_stops_early(tmp_path: Path) -> None:
    before = _reading_threads()
    path = tmp_path / "long.mcap"
    _write(path, list(range(1000, 1500)), [0] * 500, chunk_size=200)
    backend = McapReadBackend(path)
    backend.open()
    try:
        messages = backend.messages(None)
        per_chunk = len(backend._read_chunk(backend.reader.get_summary().chunk_indexes[0]))
        # Into the second chunk: the third is being read meanwhile.
        times = [next(messages).log_time_ns for _ in range(per_chunk + 2)]
        assert times == list(range(1000, 1000 + per_chunk + 2))
        assert _reading_threads() > before
        messages.close()  # type: ignore[attr-defined]
        assert _reading_threads() <= before
    finally:
        backend.close()


def test_files_merged_by_log_time_read_ahead_one_at_a_time(tmp_path: Path) -> None:
    """A split bag's files are merged by log time, each asked for its first message at once: a
    file starts reading ahead (a thread, a chunk held) only once it is read past its first chunk,
    so files that follow each other in time take one thread at a time, not one each."""
    from rose_logs.storage.records import merged_by_log_time

    before = _reading_threads()
    backends = []
    for k in range(8):
        path = tmp_path / f"split_{k}.mcap"
        _write(path, list(range(1000 * (k + 1), 1000 * (k + 1) + 60)), [0] * 60, chunk_size=200)
        backend = McapReadBackend(path)
        backend.open()
        assert len(backend.reader.get_summary().chunk_indexes) > 3
        backends.append(backend)
    try:
        most, times = 0, []
        for message in merged_by_log_time(b.messages(None) for b in backends):
            times.append(message.log_time_ns)
            most = max(most, len(_reading_threads() - before))
    finally:
        for backend in backends:
            backend.close()
    assert times == [1000 * (k + 1) + i for k in range(8) for i in range(60)]
    assert most == 1  # read ahead (one file at a time), but not eight threads at once
    assert _reading_threads() <= before
