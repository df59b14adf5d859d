"""The threaded MCAP writer: the ``mcap`` library's file byte for byte, its errors raised, not lost."""

from __future__ import annotations

import errno
import io
import random
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from rose_logs.storage.mcap_writer import ThreadedMcapWriter


def _session(writer: Any, seed: int, *, big: int = 300_000) -> None:
    """The calls a session makes, in a seeded order: schemas and channels registered before and
    between messages (one after the last), metadata and an attachment between chunks, messages
    of a few bytes to several chunks, their log times out of order, data as bytes and as views."""
    rng = random.Random(seed)
    writer.start(profile="ros2", library="rose-bag")
    first = writer.register_schema("a/msg/A", "ros2msg", b"int32 x")
    topics = [writer.register_channel("/a", "cdr", first, {"offered_qos_profiles": "- depth: 1"})]
    second = writer.register_schema("b/msg/B", "ros2msg", b"float64[] y")
    topics.append(writer.register_channel("/b", "cdr", second, {}))
    writer.add_metadata("rosbag2", {"serialized_bag_info": "{}"})
    time_ns = 1_000
    for i in range(rng.randrange(200, 1500)):
        time_ns += rng.randrange(-50, 1_000)
        data = bytes([i % 256]) * rng.choice([1, 1_000, big, 3 * 1024 * 1024])
        writer.add_message(
            rng.choice(topics), time_ns, data if i % 3 else memoryview(data), time_ns + 7, i
        )
        if i == 150:
            writer.add_attachment(5, time_ns, "calibration.yaml", "text/yaml", b"k: 1\n")
        if i == 170:
            topics.append(writer.register_channel("/c", "cdr", first, {}))
    writer.register_channel("/late", "json", 0, {})
    writer.finish()


@pytest.mark.parametrize("seed", range(4))
def test_the_file_is_the_mcap_librarys_byte_for_byte(seed: int) -> None:
    ours, theirs = io.BytesIO(), io.BytesIO()
    _session(ThreadedMcapWriter(ours), seed)
    _session(Writer(theirs), seed)
    assert ours.getvalue() == theirs.getvalue()


def test_a_file_without_messages_is_the_librarys_too() -> None:
    ours, theirs = io.BytesIO(), io.BytesIO()
    for writer in (ThreadedMcapWriter(ours), Writer(theirs)):
        writer.start(profile="ros1", library="rose-bag")
        writer.register_channel("/map", "ros1", writer.register_schema("m", "ros1msg", b"x"), {})
        writer.finish()
    assert ours.getvalue() == theirs.getvalue()


def test_the_library_reads_every_message_back_with_its_checksums(tmp_path: Path) -> None:
    path = tmp_path / "out.mcap"
    with path.open("wb") as stream:
        writer = ThreadedMcapWriter(stream, chunk_size=4096)
        writer.start(profile="ros2", library="rose-bag")
        channel = writer.register_channel("/a", "cdr", writer.register_schema("a", "m", b"x"), {})
        sent = [(t, bytes([t % 256]) * (t % 700)) for t in range(0, 5000, 7)]
        for t, data in sent:
            writer.add_message(channel, t, data, t, 0)
        writer.finish()
    with path.open("rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        assert reader.get_summary().statistics.chunk_count > 50  # type: ignore[union-attr]
        read = [(m.log_time, m.data) for _, _, m in reader.iter_messages()]
    assert read == sent


def _writing_threads() -> set[Any]:
    """The writers' threads alive (other tests' writers may still be ending theirs)."""
    import threading

    return {t for t in threading.enumerate() if t.name.startswith("rose-mcap-writer")}


class _FullDisk(io.RawIOBase):
    """A stream that takes ``room`` bytes, then fails as a full disk does."""

    def __init__(self, room: int) -> None:
        self.room = room

    def writable(self) -> bool:
        return True

    def write(self, data: Any) -> int:
        size = len(memoryview(data))
        if size > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.room -= size
        return size


def test_a_write_that_fails_on_its_thread_is_raised_by_the_writers_next_calls() -> None:
    before = _writing_threads()
    writer = ThreadedMcapWriter(_FullDisk(50_000), chunk_size=10_000)  # type: ignore[arg-type]
    writer.start()
    channel = writer.register_channel("/a", "cdr", 0, {})
    noise = random.Random(0).randbytes(1_000)  # (zeros would fit in zstd's few bytes)
    with pytest.raises(OSError, match="No space left"):
        for t in range(1_000):
            writer.add_message(channel, t, noise, t, 0)
        writer.finish()
    writer.abort()  # what the caller does next: no error, the thread ends
    assert _writing_threads() <= before  # this writer's ended


def test_finish_raises_a_failed_last_chunk_and_ends_the_thread() -> None:
    before = _writing_threads()
    writer = ThreadedMcapWriter(_FullDisk(1_000))  # type: ignore[arg-type]
    writer.start()
    channel = writer.register_channel("/a", "cdr", 0, {})
    writer.add_message(
        channel, 1, random.Random(0).randbytes(5_000), 1, 0
    )  # one chunk, written at finish
    with pytest.raises(OSError, match="No space left"):
        writer.finish()
    assert _writing_threads() <= before  # this writer's ended


class _NoThreads:
    """A thread pool whose thread cannot start (``ulimit -u``, no memory for its stack)."""

    def __init__(self, *_: object) -> None:
        pass

    def submit(self, *_: object, **__: object) -> Any:
        raise RuntimeError("can't start new thread")

    def shutdown(self, *_: object, **__: object) -> None:
        pass


def test_without_a_thread_the_caller_writes_the_same_file(monkeypatch: pytest.MonkeyPatch) -> None:
    import rose_logs.storage.mcap_writer as mcap_writer

    monkeypatch.setattr(mcap_writer, "threads_in_this_context", _NoThreads)
    ours, theirs = io.BytesIO(), io.BytesIO()
    _session(ThreadedMcapWriter(ours), 0)
    _session(Writer(theirs), 0)
    assert ours.getvalue() == theirs.getvalue()


def test_without_a_thread_a_sound_file_is_read_in_turn(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The chunk read ahead needs a thread: where none can start, the file is read as it was,
    not called corrupt ("can't start new thread" read as damage)."""
    import rose_logs.storage.mcap as storage_mcap
    from rose_logs.storage.mcap import McapReadBackend

    path = tmp_path / "sound.mcap"
    with path.open("wb") as stream:
        _session(Writer(stream, chunk_size=50_000), 1, big=20_000)
    backend = McapReadBackend(path)
    backend.open()
    try:
        ahead = [(m.log_time_ns, bytes(m.data)) for m in backend.messages(None)]
        monkeypatch.setattr(storage_mcap, "threads_in_this_context", _NoThreads)
        in_turn = [(m.log_time_ns, bytes(m.data)) for m in backend.messages(None)]
    finally:
        backend.close()
    assert len(ahead) > 100
    assert in_turn == ahead


def test_reading_at_an_offset_reads_all_in_parts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One ``pread`` returns at most 2 GiB on Linux: a larger chunk is read in parts (here parts of
    7 bytes stand for them)."""
    import rose_logs.storage.records as records

    path = tmp_path / "data.bin"
    data = bytes(range(256)) * 4
    path.write_bytes(data)
    monkeypatch.setattr(records, "_PREAD_MOST", 7)
    with path.open("rb") as f:
        assert records.read_at(f, 1000, 10) == data[10:1010]
        assert records.read_at(f, 5000, 1000) == data[1000:]  # fewer at the end


def test_an_mcap_output_whose_finish_fails_is_closed(tmp_path: Path) -> None:
    """A full disk met by the writer's thread comes out of ``close``: the output's file is closed
    there too (deleted, it held its disk space while the error lived)."""
    from rose_logs.errors import LogWriteError
    from rose_logs.writer import open_output

    out = open_output(tmp_path / "o.mcap", "mcap")
    out.open()
    out.add_topic("/chatter", "std_msgs/msg/String")
    out.write("/chatter", 1, out.typestore.types["std_msgs/msg/String"](data="hi"))
    backend = out._backend
    assert backend is not None
    stream = backend.stream  # type: ignore[attr-defined]

    def full_disk() -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    backend.writer.finish = full_disk  # type: ignore[attr-defined]
    with pytest.raises(LogWriteError, match="No space left"):
        out.close()
    assert stream.closed
    assert list(tmp_path.iterdir()) == []
