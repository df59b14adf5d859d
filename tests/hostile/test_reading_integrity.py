"""Reading never loses messages silently: CRCs, counts against the index, --salvage (exit 4), garbage maps."""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import shutil
import threading
from collections.abc import Callable
from pathlib import Path

import pytest
from make_corpus import storage_file, write_session

from rose_logs.cli import EXIT_SALVAGED, main
from rose_logs.errors import LogReadError
from rose_logs.reader import LogReader, MessageLossError, RawMessage


def _run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _flip_in_middle(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF
    path.write_bytes(bytes(data))


def test_mcap_chunk_crc_is_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "in.mcap"
    write_session(log, "mcap")
    _flip_in_middle(log)
    code, _, err = _run(capsys, "process", log, "-o", tmp_path / "o.mcap", "-q")
    assert code == 1
    assert str(log) in err and "crc" in err.lower()
    assert not (tmp_path / "o.mcap").exists()


def test_fewer_messages_than_declared_is_an_error(tmp_path: Path) -> None:
    log = tmp_path / "bag"
    total = write_session(log, "db3")
    meta = log / "metadata.yaml"
    meta.write_text(meta.read_text().replace("message_count: 12", "message_count: 20"))
    with LogReader(log) as reader, pytest.raises(MessageLossError, match=f"of {total + 8}"):
        for _ in reader.messages():
            pass


def test_salvage_keeps_what_was_read_and_exits_4(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "bag"
    write_session(log, "mcap-dir")
    meta = log / "metadata.yaml"
    meta.write_text(meta.read_text().replace("message_count: 12", "message_count: 20"))
    out, report = tmp_path / "o", tmp_path / "r.json"
    code, _, err = _run(capsys, "process", log, "-o", out, "--json", report, "-q")
    assert code == 1 and "--salvage" in err
    assert not out.exists() and not report.exists()
    code, _, err = _run(capsys, "process", log, "-o", out, "--json", report, "-q", "--salvage")
    assert code == EXIT_SALVAGED
    assert "warning:" in err and "damaged" in err
    assert out.is_dir()
    data = json.loads(report.read_text())
    assert data["losses"] and data["message_count"] == 15
    # A gate that fails is named although the salvage decides the exit code (said nothing before).
    code, _, err = _run(
        capsys, "process", log, "--no-output", "-q", "--salvage", "--fail-above", "0.0001"
    )
    assert code == EXIT_SALVAGED
    assert "exceeds --fail-above 0.0001" in err


def test_a_salvaged_log_reports_the_time_range_it_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A damaged last chunk: the report ends at the last message read, not where the index says
    the log ended (the summary said 65 s of a log cut after 5 s)."""
    log, out, report = tmp_path / "in.mcap", tmp_path / "o.mcap", tmp_path / "r.json"
    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    data = bytearray(sample.read_bytes())
    data[_chunk_starts(sample)[-1] + 5_000] ^= 0xFF  # in the last of its chunks
    log.write_bytes(bytes(data))
    with LogReader(sample) as reader:
        declared_end = reader.end_ns
    code, _, _ = _run(capsys, "process", log, "-o", out, "--json", report, "-q", "--salvage")
    assert code == EXIT_SALVAGED
    with LogReader(out) as reader:
        read_end = max(m.log_time_ns for m in reader.messages())
    data = json.loads(report.read_text())
    assert data["end_ns"] == read_end < declared_end


def _chunk_starts(path: Path) -> list[int]:
    from mcap.reader import make_reader

    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    return sorted(c.chunk_start_offset for c in summary.chunk_indexes)


def test_salvage_skips_only_the_damaged_chunk_of_an_indexed_mcap(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One flipped bit in the second of seven chunks lost the six after it too: the index leads
    past the damage, so only that chunk's ten seconds are lost."""
    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    starts = _chunk_starts(sample)
    assert len(starts) >= 4
    data = bytearray(sample.read_bytes())
    data[starts[1] + 5_000] ^= 0xFF
    log, out, report = tmp_path / "in.mcap", tmp_path / "o.mcap", tmp_path / "r.json"
    log.write_bytes(bytes(data))
    err = _refused_then_salvaged(capsys, log, out, report, refusal="corrupt")
    assert err.count("skipped a damaged chunk at byte") == 1, err
    assert f"at byte {starts[1]} of {len(data)}" in err
    whole = {(m.channel.topic, m.log_time_ns): bytes(m.data) for m in _read(sample)}
    kept = {(m.channel.topic, m.log_time_ns): bytes(m.data) for m in _read(out)}
    salvaged = json.loads(report.read_text())
    lost = [key for key in whole if key not in kept]
    # What is lost is one chunk's time span; everything else is there, byte for byte, up to the end.
    assert lost and len(lost) < len(whole) / 3
    assert all(kept[key] == whole[key] for key in kept if key in whole)
    assert max(t for _, t in kept) == max(t for _, t in whole)
    assert salvaged["end_ns"] == max(t for _, t in whole)
    maps = [t for topic, t in whole if topic == "/map"]
    assert 0 < len(salvaged["snapshots"]) < len(maps)
    assert len(salvaged["snapshots"]) == sum(1 for t in maps if ("/map", t) in kept)


def test_info_on_a_damaged_log_is_one_error_line_or_with_salvage_the_readable_part(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """info printed half its report, then the error; it had no --salvage to look past the damage."""
    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    data = bytearray(sample.read_bytes())
    data[_chunk_starts(sample)[1] + 5_000] ^= 0xFF
    log = tmp_path / "in.mcap"
    log.write_bytes(bytes(data))
    code, out, err = _run(capsys, "info", log)
    assert code == 1 and out == ""
    assert err.startswith(f"error: {log}: corrupt") and "--salvage" in err
    assert err.count("\n") == 1
    code, out, err = _run(capsys, "info", log, "--salvage")
    assert code == EXIT_SALVAGED
    assert "messages     715 (declared)" in out and "grid sizes   1152 x 736" in out
    assert "\nlosses       " in out and "skipped a damaged chunk" in out
    assert "/map 12 of 14" in out and "warning:" in err
    # Cut off: read record by record, the counts are what was read, not declared.
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(sample.read_bytes()[: len(data) * 6 // 10])
    code, out, _ = _run(capsys, "info", cut, "--salvage")
    assert code == EXIT_SALVAGED and "(declared)" not in out and "\nlosses       " in out
    code, out, _ = _run(capsys, "info", sample, "--salvage")  # nothing lost: as without
    assert code == 0 and "losses" not in out and "(declared)" not in out
    assert (code, out) == _run(capsys, "info", sample)[:2]


def _read(path: Path) -> list[RawMessage]:
    with LogReader(path) as reader:
        return list(reader.messages())


@pytest.mark.parametrize("chunked", [True, False])
def test_salvage_reads_an_intact_indexed_mcap_as_the_index_orders_it(
    tmp_path: Path, chunked: bool
) -> None:
    """The salvaging reader merges the chunks itself: on an intact file it gives what the mcap
    library gives, in the same order, also for chunks that overlap in time and equal log times,
    and for a file of no chunks (it read nothing of one; read in file order)."""
    from mcap.writer import Writer

    log = tmp_path / "overlap.mcap"
    with log.open("wb") as stream:
        writer = Writer(stream, chunk_size=300, use_chunking=chunked)
        writer.start(profile="", library="test")
        channels = [writer.register_channel(f"/t{k}", "json", 0) for k in range(3)]
        times = [5, 3, 3, 9, 1, 3, 7, 7, 2, 8, 3, 6] * 4
        for n, t in enumerate(times):
            writer.add_message(channels[n % 3], t, f'{{"n": {n}}}'.encode(), t)
        writer.finish()
    assert len(_chunk_starts(log)) > 3 if chunked else not _chunk_starts(log)
    plain = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in _read(log)]
    with LogReader(log, salvage=True) as reader:
        salvaged = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        assert not reader.losses
    if not chunked:
        # Salvaged in file order (sorting first would read the whole file before one message, and
        # keep nothing of a damaged one): the same messages.
        assert [t for _, t, _ in salvaged] == times
        salvaged, plain = sorted(salvaged), sorted(plain)
    assert salvaged == plain and len(plain) == len(times)
    with LogReader(log, salvage=True) as reader:
        some = [(m.channel.topic, m.log_time_ns) for m in reader.messages(topics={"/t1"})]
    assert sorted(some) == sorted((topic, t) for topic, t, _ in plain if topic == "/t1")


def test_truncated_mcap_with_salvage_is_never_exit_0(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "bag"
    write_session(log, "mcap-dir")
    storage = storage_file(log)
    storage.write_bytes(storage.read_bytes()[: storage.stat().st_size * 9 // 10])
    code, _, _ = _run(capsys, "process", log, "--no-output", "--salvage", "-q")
    assert code in (1, EXIT_SALVAGED)


def _refused_then_salvaged(
    capsys: pytest.CaptureFixture[str], log: Path, out: Path, report: Path, *, refusal: str
) -> str:
    """``process`` refuses the damaged ``log`` naming ``--salvage`` (writing nothing), then salvages
    it with exit 4; returns the second run's stderr."""
    code, _, err = _run(capsys, "process", log, "-o", out, "-q")
    assert code == 1 and refusal in err and "--salvage" in err
    assert not out.exists()
    code, summary, err = _run(
        capsys, "process", log, "-o", out, "--json", report, "-q", "--salvage"
    )
    assert code == EXIT_SALVAGED
    assert "\nlosses       " in summary  # the summary lists them too, as the README says
    return err


def test_salvage_keeps_the_readable_start_of_a_truncated_mcap_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording cut off by a crash has no index at its end: an error without --salvage, and with
    it every message of the complete chunks before the cut, exit 4."""
    whole = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    data = whole.read_bytes()
    log = tmp_path / "cut.mcap"
    log.write_bytes(data[: len(data) * 6 // 10])
    out, report = tmp_path / "o.mcap", tmp_path / "r.json"
    err = _refused_then_salvaged(capsys, log, out, report, refusal="truncated MCAP")
    assert err.count("end of the file is missing or damaged") == 1, err  # said once
    assert err.count("error:") == 0
    salvaged = json.loads(report.read_text())
    with LogReader(whole) as reader:
        total = reader.message_count
        maps_before_cut = sum(
            1 for m in reader.messages(topics={"/map"}) if m.log_time_ns <= salvaged["end_ns"]
        )
    assert 0 < salvaged["message_count"] < total
    assert salvaged["losses"]
    assert len(salvaged["snapshots"]) == maps_before_cut
    with LogReader(out) as reader:  # the output is a complete, indexed file
        assert reader.message_count >= salvaged["message_count"]


def _data_end(path: Path) -> int:
    """The byte just after the DataEnd record of an MCAP file (where its summary begins)."""
    from mcap.records import DataEnd
    from mcap.stream_reader import StreamReader

    with path.open("rb") as stream:
        for record in StreamReader(stream, skip_magic=False).records:
            if isinstance(record, DataEnd):
                return stream.tell()
    raise AssertionError(f"{path}: no DataEnd record")


@pytest.mark.parametrize("command", [["info"], ["process", "--no-output"]])
def test_an_mcap_file_cut_after_its_data_is_said_to_be_cut_short(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str]
) -> None:
    """Cut right after DataEnd (every message there, the summary and footer gone), the file read
    "corrupt or truncated MCAP file ... (HEADER record has length 292452500802371597 that exceeds
    limit 217568)": the library's reading of the footer where the file now ends."""
    whole = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    log = tmp_path / "cut.mcap"
    log.write_bytes(whole.read_bytes()[: _data_end(whole)])
    code, _, err = _run(capsys, command[0], log, *command[1:])
    assert code == 1
    assert err.startswith(f"error: {log}: truncated MCAP file, cut short: ") and "--salvage" in err
    assert "record has length" not in err and len(err.splitlines()) == 1, err


@pytest.mark.parametrize("back", [37, 30, 29])  # the footer's op, and bytes of its length
def test_an_mcap_file_with_a_damaged_footer_loses_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], back: int
) -> None:
    """A damaged footer (its record length) after an intact data section read as an index that
    cannot be read (exit 1), and with --salvage as a loss (exit 4) with every message kept: read
    as a damaged summary is, record by record, with a warning, exit 0."""
    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    data = bytearray(sample.read_bytes())
    data[len(data) - back] ^= 0x41
    log, out = tmp_path / "in.mcap", tmp_path / "o.mcap"
    log.write_bytes(bytes(data))
    for salvage in ([], ["--salvage"]):
        code, summary, err = _run(capsys, "process", log, "-o", out, "-q", "--force", *salvage)
        assert code == 0, err
        assert "losses" not in summary and "error" not in err
        assert err.count("the footer is damaged") == 1, err
        assert "nothing lost" in err
        whole = _messages(sample)
        topics = {topic for topic, _, _ in whole}
        assert [m for m in _messages(out) if m[0] in topics] == whole
    assert log.read_bytes() == bytes(data)  # the input never modified


@pytest.fixture(scope="module")
def ros1_bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[tuple[int, int]]]:
    """A ROS 1 bag of several chunks (a CARMEN session) and each chunk's ``(position, messages)``."""
    from rosbags.rosbag1 import Reader

    log = Path(__file__).resolve().parents[1] / "data" / "radish_carmen_corrected_logs"
    bag = tmp_path_factory.mktemp("ros1") / "s.bag"
    argv = ["convert", str(log / "freiburg-101-corrected.log.gz"), str(bag), "-q"]
    assert main([*argv, "--resolution", "0.1", "--map-period", "60"]) == 0
    with Reader(bag) as reader:
        chunks = [(c.pos, sum(c.connection_counts.values())) for c in reader.chunk_infos]
    assert len(chunks) >= 4
    return bag, chunks


def _messages(path: Path, *, salvage: bool = False) -> list[tuple[str, int, bytes]]:
    with LogReader(path, salvage=salvage) as reader:
        return [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]


def _in_file_order(bag: Path) -> list[tuple[str, int, bytes]]:
    """Every message of an intact bag read record by record (the salvage reader), checked against
    rosbags' indexed reading: the same messages."""
    from rose_logs.storage.ros1_stream import Ros1StreamReadBackend

    backend = Ros1StreamReadBackend(bag)
    try:
        backend.open()
        streamed = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in backend.messages(None)]
    finally:
        backend.close()
    assert sorted(streamed) == sorted(_messages(bag))
    return streamed


def _other_bag(path: Path) -> bytes:
    """The bytes of another ROS 1 bag (strings on ``/other``, written by rosbags)."""
    from rosbags.rosbag1 import Writer

    with Writer(path) as writer:
        conn = writer.add_connection("/other", "std_msgs/msg/String", msgdef="string data", md5sum="992ce8a1687cec8c8bd883ec73ca41d1")  # fmt: skip
        for i in range(2000):
            writer.write(conn, 10**18 + i, (5).to_bytes(4, "little") + b"other")
    return path.read_bytes()


@pytest.mark.parametrize("salvage", [False, True])
@pytest.mark.parametrize("change", ["written over", "written to", "cut", "replaced"])
def test_a_ros1_bag_changed_while_read_is_said_so_not_damaged(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    ros1_bag: tuple[Path, list[tuple[int, int]]],
    change: str,
    salvage: bool,
) -> None:
    """A bag overwritten, cut short or replaced by another program while it was read was said
    to be damaged ("the bag's index is damaged", "corrupt or truncated log"), and --salvage
    lost its chunks one by one as damaged (exit 4, or kept the other file's messages): now an
    error that says the file changed while it was read."""
    bag = tmp_path / "s.bag"
    shutil.copyfile(ros1_bag[0], bag)
    whole = bag.read_bytes()
    other = _other_bag(tmp_path / "other.bag")
    with LogReader(bag, salvage=salvage) as reader, pytest.raises(LogReadError) as raised:
        for n, _ in enumerate(reader.messages()):
            if n == 20:
                if change == "written over":
                    with bag.open("r+b") as stream:
                        stream.write(other)
                elif change == "written to":  # inside, its size and ends as they were
                    with bag.open("r+b") as stream:
                        stream.seek(len(whole) // 2)
                        stream.write(bytes(range(256)) * 80)
                elif change == "cut":
                    os.truncate(bag, len(whole) // 2)
                else:
                    (tmp_path / "other.bag").replace(bag)
    said = str(raised.value)
    assert said.startswith(f"{bag}: the file changed while it was read ("), said
    assert "damaged" not in said and not reader.losses
    # Left alone, the same bag reads whole; one that only grew (a recording still being
    # written) is read as before.
    shutil.copyfile(ros1_bag[0], bag)
    assert len(_messages(bag)) == sum(n for _, n in ros1_bag[1])
    active = tmp_path / "s.bag.active"
    active.write_bytes(whole[: len(whole) // 2])
    with LogReader(active, salvage=True) as reader:
        for n, _ in enumerate(reader.messages()):
            if n == 20:
                with active.open("ab") as stream:
                    stream.write(whole[len(whole) // 2 :])
        assert n > 20 and len(reader.losses) == 1, reader.losses


#: A time of 2106 (its seconds' high bits flipped), in a ROS 1 record's 8 bytes.
_FAR_TIME = (0xFFFFFF00).to_bytes(4, "little") + bytes(4)


def _ros1_bag_with_a_far_time(path: Path, where: str, chunk_k: int = 1) -> list[int]:
    """A ROS 1 bag of 400 strings on two topics, 10 ms apart, in 11 chunks, with one time
    damaged to 2106 (``where``: the ``chunk_k``-th chunk's info's start or end time, the time
    of its first message's record, or that message's index entry; ``none``: none); returns the
    messages' times."""
    import struct

    from rosbags.rosbag1 import Writer

    from rose_logs.storage.ros1_stream import _read_record, read_index

    times = [10**18 + i * 10**7 for i in range(400)]
    writer = Writer(path)
    writer.chunk_threshold = 2000
    with writer:
        conns = [
            writer.add_connection(
                f"/t{k}",
                "std_msgs/msg/String",
                msgdef="string data",
                md5sum="992ce8a1687cec8c8bd883ec73ca41d1",
            )
            for k in range(2)
        ]
        for i, time in enumerate(times):
            writer.write(conns[i % 2], time, (3).to_bytes(4, "little") + b"abc")
    if where == "none":
        return times
    data = bytearray(path.read_bytes())
    index = read_index(path)
    chunk = index.chunks[chunk_k]
    if where.startswith("info"):
        name = b"start_time=" if where == "info start" else b"end_time="
        at = index.index_pos
        for _ in range(chunk_k + 1):  # the chunk's info
            at = data.find(name, at + 1)
        at += len(name)
    elif where == "message":
        at = data.find(b"time=", chunk.pos + 1) + len(b"time=")
    else:  # the first entry of the index data record after the chunk
        stream = io.BytesIO(bytes(data))
        stream.seek(chunk.pos)
        _read_record(stream, len(data))
        at = stream.tell() + 4 + struct.unpack_from("<I", data, stream.tell())[0] + 4
    data[at : at + 8] = _FAR_TIME
    path.write_bytes(bytes(data))
    return times


@pytest.mark.parametrize("chunk_k", [1, 0])
@pytest.mark.parametrize("salvage", [False, True])
@pytest.mark.parametrize("where", ["info start", "info end", "message", "index entry"])
def test_a_ros1_time_damaged_to_a_far_future_is_left_out_not_taken(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, where: str, salvage: bool, chunk_k: int
) -> None:
    """A bit flipped in a ROS 1 time: a chunk info's end of 2106 made a session of 4 s span 83
    years (with or without --salvage), a chunk info's start of 2106 had --salvage hand that
    chunk's messages out last, out of order, and a message's own time of 2106 was taken by
    --salvage, unsaid (a snapshot 83 years on). A chunk's times are now those its info and its
    index entries agree on (said when they differ), and --salvage skips a message outside its
    chunk's times as damaged, said as a loss. In the first chunk (``chunk_k`` 0), its first
    message's index entry of 2106 moved both ends of the entries' times: the log started at
    the second message, after the first."""
    import logging

    bag = tmp_path / "t.bag"
    times = _ros1_bag_with_a_far_time(bag, where, chunk_k)
    with caplog.at_level(logging.WARNING), LogReader(bag, salvage=salvage) as reader:
        try:
            read = [m.log_time_ns for m in reader.messages()]
        except LogReadError as err:  # the index entry disagrees with its message: as before
            assert where in ("message", "index entry") and not salvage
            assert "an index entry does not match the message it points to" in str(err)
            return
        assert (reader.start_ns, reader.end_ns) == (times[0], times[-1])
        losses = reader.losses
    assert read == sorted(read)
    if where == "message":  # skipped, said
        assert len(read) == len(times) - 1 and set(read) < set(times)
        assert losses[0].startswith(f"{bag}: skipped a message of the chunk at byte ")
        assert "at 4294967040000000000 ns, outside the chunk's" in losses[0]
    else:  # its message read, at its time
        assert read == times and not losses
    if where != "message":  # the chunk info and the index entries disagree: said
        assert "gives other times than its messages' index entries" in caplog.text


@pytest.mark.parametrize("where", ["info start", "info end"])
def test_a_ros1_chunk_info_time_damaged_beside_a_damaged_chunk_is_left_out(
    tmp_path: Path, where: str
) -> None:
    """A bag that rosbags cannot open (a chunk's record damaged), which --salvage reads
    through its own reading of the index, took its time range from the chunk infos alone: a
    chunk info's end of 2106 beside the damaged chunk made a session of 4 s span 83 years (and
    a start of 2106 read that chunk last). It now takes a chunk's times as its info and the
    index entries after it agree on, as the reading through rosbags does."""
    from rose_logs.storage.ros1_stream import Ros1IndexedReadBackend, read_index

    bag = tmp_path / "t.bag"
    times = _ros1_bag_with_a_far_time(bag, where)
    data = bytearray(bag.read_bytes())
    data[read_index(bag).chunks[4].pos + 5] ^= 0xFF  # another chunk's record header
    bag.write_bytes(bytes(data))
    with LogReader(bag, salvage=True) as reader:
        read = [m.log_time_ns for m in reader.messages()]
        assert isinstance(reader._open_backend, Ros1IndexedReadBackend)
        assert (reader.start_ns, reader.end_ns) == (times[0], times[-1])
        losses = reader.losses
    assert read == sorted(read) and 300 < len(read) < len(times)
    assert "skipped a damaged chunk at byte" in losses[0]


def test_a_ros1_chunks_index_data_record_damaged_leaves_its_times_as_its_info_gives_them(
    tmp_path: Path,
) -> None:
    """A bag that rosbags cannot open (a chunk's record damaged), read by --salvage through its
    own reading of the index, whose last chunk's index data record of /t1 does not read: the
    entries of /t0 alone gave that chunk's times, and the log ended at its last /t0 message,
    10 ms before its last message (read, at its time). A chunk whose entries are not all read
    has its info's times."""
    import struct

    from rose_logs.storage.ros1_stream import Ros1IndexedReadBackend, _read_record, read_index

    bag = tmp_path / "t.bag"
    times = _ros1_bag_with_a_far_time(bag, "none")  # (no time damaged)
    data = bytearray(bag.read_bytes())
    index = read_index(bag)
    stream = io.BytesIO(bytes(data))
    stream.seek(index.chunks[-1].pos)
    _read_record(stream, len(data))  # the chunk
    _read_record(stream, len(data))  # its index data record of /t0
    data[stream.tell() : stream.tell() + 4] = struct.pack("<I", 10**6)  # /t1's header length
    data[index.chunks[4].pos + 5] ^= 0xFF  # another chunk's record header
    bag.write_bytes(bytes(data))
    with LogReader(bag, salvage=True) as reader:
        read = [m.log_time_ns for m in reader.messages()]
        assert isinstance(reader._open_backend, Ros1IndexedReadBackend)
        assert (reader.start_ns, reader.end_ns) == (times[0], times[-1])
    assert read[-1] == times[-1]


@pytest.mark.parametrize("fmt", ["db3", "mcap-dir"])
def test_a_bag_folders_storage_file_changed_while_read_is_said_so(tmp_path: Path, fmt: str) -> None:
    """A ROS 2 bag folder's storage file cut short while it was read was said to be a corrupt
    log ("disk I/O error", "Truncated record"), and one written into read as sound: the error
    now names the file and says it changed while it was read."""
    bag = tmp_path / "bag"
    write_session(bag, fmt)
    storage = storage_file(bag)
    whole = storage.read_bytes()
    for salvage in (False, True):
        storage.write_bytes(whole)
        with LogReader(bag, salvage=salvage) as reader, pytest.raises(LogReadError) as raised:
            for n, _ in enumerate(reader.messages()):
                if n == 2:
                    os.truncate(storage, storage.stat().st_size // 2)
        assert str(raised.value).startswith(f"{storage}: the file changed while it was read (cut")
        assert not reader.losses


def test_a_db3_a_recording_writes_to_while_read_is_said_so(tmp_path: Path) -> None:
    """A .db3 bag being recorded is written in place (SQLite rewrites its header at every
    transaction). rosbags reads it ``immutable``, without SQLite's locks: the pages change under
    the reading (a recorder's inserts among the messages read made it 'database disk image is
    malformed', or lost and reordered messages). It was read as sound (71faa11); it is said to
    have changed, as a file written to is."""
    import sqlite3

    bag = tmp_path / "bag"
    write_session(bag, "db3", maps=[{}] * 2, scans_per_map=150)
    storage = storage_file(bag)
    with LogReader(bag) as reader, pytest.raises(LogReadError) as caught:
        for n, _ in enumerate(reader.messages()):
            if n == 2:  # a recorder's transactions
                with sqlite3.connect(storage) as db:
                    for _ in range(20):
                        db.execute(
                            "INSERT INTO messages (topic_id, timestamp, data) SELECT topic_id, "
                            "(SELECT max(timestamp) FROM messages) + 1, data "
                            "FROM messages WHERE id = 3"
                        )
                        db.commit()
    assert str(storage) in str(caught.value)
    assert "changed while it was read (written to as an SQLite database" in str(caught.value)


def test_a_reading_stopped_early_still_says_what_salvage_skipped(tmp_path: Path) -> None:
    """A reading stopped before its end (a caller that breaks off, an interrupted session)
    says what --salvage skipped so far, as before the check that the file did not change under
    the reader (which left it unsaid)."""
    bag = tmp_path / "t.bag"
    _ros1_bag_with_a_far_time(bag, "message")
    with LogReader(bag, salvage=True) as reader:
        messages = reader.messages()
        for n, _ in enumerate(messages):
            if n == 300:  # well past the second chunk, whose message was skipped
                break
        messages.close()
        assert len(reader.losses) == 1
        assert reader.losses[0].startswith(f"{bag}: skipped a message of the chunk at byte ")


@pytest.mark.parametrize("where", ["message", "index entry"])
def test_salvage_of_a_ros1_bag_without_index_skips_a_message_whose_time_is_damaged(
    tmp_path: Path, where: str
) -> None:
    """A recording that was not closed (no index at its end), read record by record by
    --salvage: a message whose time was damaged to 2106 was kept without a word (the session
    spanned 83 years). Its time disagrees with its index entry after its chunk: it is skipped,
    said as a loss. Where the entry is the damaged one (the message's time beside its chunk's
    others), the message was skipped as well, though the indexed reading keeps it: it is kept."""
    from rose_logs.storage.ros1_stream import read_index

    whole = tmp_path / "t.bag"
    times = _ros1_bag_with_a_far_time(whole, where)
    active = tmp_path / "t.bag.active"
    active.write_bytes(whole.read_bytes()[: read_index(whole).index_pos])
    with LogReader(active, salvage=True) as reader:
        read = [m.log_time_ns for m in reader.messages()]
        assert (reader.start_ns, reader.end_ns) == (times[0], times[-1])
        losses = reader.losses
    if where == "index entry":
        assert read == times
        assert len(losses) == 1 and "kept the 400 messages before it" in losses[0]
        return
    assert len(read) == len(times) - 1 and set(read) < set(times)
    assert "kept the 399 messages before it" in losses[0]
    assert losses[1].startswith(f"{active}: skipped a message of the chunk at byte ")
    assert "at 4294967040000000000 ns, its index entry says" in losses[1]
    assert len(losses) == 2


def test_salvage_keeps_the_complete_chunks_of_a_truncated_ros1_bag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bag: tuple[Path, list]
) -> None:
    bag, chunks = ros1_bag
    (start, _), (end, _) = chunks[2], chunks[3]
    cut = tmp_path / "cut.bag"
    cut.write_bytes(bag.read_bytes()[: (start + end) // 2])  # in the middle of the third chunk
    out, report = tmp_path / "o.bag", tmp_path / "r.json"
    err = _refused_then_salvaged(capsys, cut, out, report, refusal="truncated ROS 1 bag")
    assert err.count("index is missing or damaged") == 1, err
    kept = sum(count for _, count in chunks[:2])
    assert _messages(cut, salvage=True) == _in_file_order(bag)[:kept]
    assert json.loads(report.read_text())["message_count"] == kept
    with LogReader(out) as reader:  # a complete, indexed bag: the two chunks and our topics
        topics = {c.topic for c in reader.channels}
        assert {"/map", "/scan", "/map/rose/cleaned"} <= topics


def test_salvage_reads_a_ros1_bag_that_was_never_closed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bag: tuple[Path, list]
) -> None:
    """``rosbag record`` killed: the header's index position is 0 and no index follows the chunks."""
    bag, chunks = ros1_bag
    data = bytearray(bag.read_bytes()[: chunks[3][0]])  # three whole chunks
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = bytes(8)
    active = tmp_path / "s.bag.active"
    active.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", active, "--no-output", "-q")
    assert code == 1 and "not closed?" in err and "--salvage" in err
    code, _, err = _run(capsys, "process", active, "--no-output", "-q", "--salvage")
    assert code == EXIT_SALVAGED
    assert "the recording was not closed" in err
    kept = sum(count for _, count in chunks[:3])
    assert _messages(active, salvage=True) == _in_file_order(bag)[:kept]


@pytest.mark.parametrize("compression", ["BZ2", "LZ4"])
def test_the_record_by_record_reader_decompresses_ros1_chunks(
    tmp_path: Path, compression: str
) -> None:

    plain, packed = tmp_path / "plain.bag", tmp_path / "packed.bag"
    write_session(plain, "ros1")
    _rewrite_bag(plain, packed, compression)
    assert _in_file_order(packed)  # every message, as rosbags reads them


@pytest.fixture(scope="module")
def ros1_bags(
    ros1_bag: tuple[Path, list], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, Path]:
    """The CARMEN session bag as written (uncompressed chunks) and rewritten with bz2 and lz4
    chunks, each of several chunks."""

    bag, _ = ros1_bag
    bags = {"none": bag}
    for compression in ("bz2", "lz4"):
        packed = tmp_path_factory.mktemp("ros1") / f"{compression}.bag"
        _rewrite_bag(bag, packed, compression.upper(), chunk_threshold=200_000)
        bags[compression] = packed
    return bags


def _rewrite_bag(
    source: Path, target: Path, compression: str, *, chunk_threshold: int | None = None
) -> None:
    """``source`` (a ROS 1 bag) written again by rosbags with ``compression`` (``BZ2``, ``LZ4``)
    chunks, of ``chunk_threshold`` bytes when given."""
    from rosbags.rosbag1 import Reader, Writer

    with Reader(source) as reader:
        writer = Writer(target)
        writer.set_compression(getattr(Writer.CompressionFormat, compression))
        if chunk_threshold is not None:
            writer.chunk_threshold = chunk_threshold
        with writer:
            conns = {
                c.id: writer.add_connection(
                    c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest,
                    callerid=c.ext.callerid, latching=c.ext.latching,
                )
                for c in reader.connections
            }  # fmt: skip
            for conn, t, data in reader.messages():
                writer.write(conns[conn.id], t, data)


def _chunk_infos(bag: Path) -> list[tuple[int, int, int]]:
    """``(position, messages, end time ns)`` of each chunk of ``bag``, in file order."""
    from rosbags.rosbag1 import Reader

    with Reader(bag) as reader:
        infos = [
            (int(c.pos), sum(c.connection_counts.values()), int(c.end_time) - 1)
            for c in reader.chunk_infos
        ]
    return sorted(infos)


def _damage_a_middle_chunk(bag: Path, out: Path, where: str) -> tuple[int, int]:
    """A copy of ``bag`` with one byte flipped in its middle chunk: in the record's header (the
    '=' of its first field) or at the start of its data (the first record's length, or the
    compressed stream's magic); the chunk's ``(position, messages)``."""
    import struct

    data = bytearray(bag.read_bytes())
    chunks = _chunk_infos(bag)
    assert len(chunks) >= 4
    pos, count, _ = chunks[len(chunks) // 2]
    if where == "header":
        at = data.index(b"=", pos + 8)
    else:
        header_length = struct.unpack_from("<I", data, pos)[0]
        at = pos + 4 + header_length + 4 + 3
    data[at] ^= 0x5A
    out.write_bytes(bytes(data))
    return pos, count


@pytest.mark.parametrize("where", ["payload", "header"])
@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_salvage_skips_only_the_damaged_chunk_of_a_ros1_bag(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    ros1_bags: dict[str, Path],
    compression: str,
    where: str,
) -> None:
    """One flipped byte in a middle chunk lost every chunk after it (1 of 14 maps kept), and a
    damaged chunk header was said as an index that cannot be read although the index was intact:
    the index leads past the damaged chunk, as for MCAP."""
    bag = ros1_bags[compression]
    log = tmp_path / "in.bag"
    pos, count = _damage_a_middle_chunk(bag, log, where)
    size = log.stat().st_size
    code, _, err = _run(capsys, "process", log, "--no-output", "-q")
    assert code == 1 and len(err.splitlines()) == 1, err
    assert err.startswith(
        f"error: {log}: the chunk at byte {pos} of {size} is damaged, the index intact: "
        f"--salvage skips its {count} message(s) ("
    )
    assert "index cannot be read" not in err
    out, report = tmp_path / "o.bag", tmp_path / "r.json"
    code, summary, err = _run(
        capsys, "process", log, "-o", out, "--json", report, "-q", "--salvage"
    )
    assert code == EXIT_SALVAGED, err
    assert "\nlosses       " in summary
    assert err.count("skipped a damaged chunk at byte") == 1, err
    assert f"at byte {pos} of {size}" in err
    whole = _messages(bag)
    with LogReader(log, salvage=True) as reader:
        kept = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        losses = reader.losses
    # That chunk's messages only are lost; the others come in the order of the intact bag.
    assert len(kept) == len(whole) - count
    assert kept == [m for m in whole if m in set(kept)]
    assert max(t for _, t, _ in kept) == max(t for _, t, _ in whole)
    assert any(f"read {len(kept)} of {len(whole)} messages the log declares" in x for x in losses)
    salvaged = json.loads(report.read_text())
    maps = [t for topic, t, _ in whole if topic == "/map"]
    assert len(salvaged["snapshots"]) == sum(1 for topic, _, _ in kept if topic == "/map")
    assert len(maps) / 2 < len(salvaged["snapshots"]) <= len(maps)
    with LogReader(out) as reader:  # a complete bag of what was kept
        assert reader.message_count >= len(kept)


def test_salvage_reads_past_damaged_index_entries_of_a_ros1_bag_and_loses_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bags: dict[str, Path]
) -> None:
    """A damaged index data record after a middle chunk (rosbags cannot open the bag) kept only
    the chunks before it: the chunks are read through the chunk infos, every message kept."""
    bag = ros1_bags["bz2"]
    data = bytearray(bag.read_bytes())
    pos = _chunk_infos(bag)[len(_chunk_infos(bag)) // 2][0]
    data[data.index(b"op=\x04", pos) + 2] ^= 0x5A  # its op field loses its '='
    log = tmp_path / "in.bag"
    log.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", log, "--no-output", "-q")
    assert code == 1 and "--salvage" in err and len(err.splitlines()) == 1
    code, _, err = _run(capsys, "process", log, "--no-output", "-q", "--salvage")
    assert code == 0, err
    assert "read chunk by chunk through its chunk infos" in err
    with LogReader(log, salvage=True) as reader:
        kept = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        assert not reader.losses
    assert kept == _messages(bag)


def _index_data_after(data: bytes, pos: int) -> list[tuple[int, int, int]]:
    """``(byte of its first offset, connection id, count)`` of each index data record that follows
    the chunk record at ``pos`` of the ROS 1 bag ``data``."""
    import struct

    def record_end(at: int) -> tuple[int, dict[bytes, bytes], int]:
        header_length = struct.unpack_from("<I", data, at)[0]
        header, fields, i = data[at + 4 : at + 4 + header_length], {}, 0
        while i < len(header):
            n = struct.unpack_from("<I", header, i)[0]
            name, _, value = header[i + 4 : i + 4 + n].partition(b"=")
            fields[bytes(name)] = bytes(value)
            i += 4 + n
        data_at = at + 4 + header_length + 4
        return data_at, fields, data_at + struct.unpack_from("<I", data, data_at - 4)[0]

    _, _, at = record_end(pos)
    found = []
    while at < len(data):
        data_at, fields, end = record_end(at)
        if fields[b"op"] != b"\x04":
            break
        count = struct.unpack("<I", fields[b"count"])[0]
        found.append((data_at + 8, struct.unpack("<I", fields[b"conn"])[0], count))
        at = end
    return found


@pytest.mark.parametrize("compression", ["none", "lz4"])
@pytest.mark.parametrize("damage", ["repeated", "another connection's"])
def test_salvage_reads_maps_through_the_index_data_and_past_offsets_that_disagree(
    tmp_path: Path, ros1_bags: dict[str, Path], compression: str, damage: str
) -> None:
    """--salvage read every record of every chunk holding a map (4x slower than rosbags on an
    intact bag's maps): it now reads the map records where the chunk's index data records place
    them. An offset that points to a record already listed, or to another connection's, is damage:
    that chunk is read record by record, and nothing is lost or repeated."""
    import struct

    bag = ros1_bags[compression]
    data = bytearray(bag.read_bytes())
    chunks = _chunk_infos(bag)
    entries = next(
        found
        for found in (_index_data_after(data, pos) for pos, _, _ in chunks[len(chunks) // 2 :])
        if len(found) >= 2 and any(count >= 2 for _, _, count in found)
    )
    at, _, _ = next(entry for entry in entries if entry[2] >= 2)
    # Its second offset made its first, or another connection's first.
    source = at if damage == "repeated" else next(a for a, _, _ in entries if a != at)
    offset = struct.unpack_from("<I", data, source)[0]
    struct.pack_into("<I", data, at + 12, offset)
    log = tmp_path / "in.bag"
    log.write_bytes(bytes(data))
    for topics in (None, {"/map"}, {"/scan"}):
        with LogReader(bag) as reader:
            intact = [
                (m.channel.topic, m.log_time_ns, bytes(m.data))
                for m in reader.messages(topics=topics)
            ]
        for path in (bag, log):
            with LogReader(path, salvage=True) as reader:
                read = [
                    (m.channel.topic, m.log_time_ns, bytes(m.data))
                    for m in reader.messages(topics=topics)
                ]
                assert not reader.losses
            assert read == intact, (path, topics)


def _first_index_entries(data: bytes, chunk_pos: int) -> int:
    """Where the data of the first index data record after the chunk at ``chunk_pos`` starts: its
    length (4 bytes), then an entry (time sec, time nsec, offset; 4 bytes each) per message."""
    import struct

    header_length = struct.unpack_from("<I", data, chunk_pos)[0]
    at = chunk_pos + 4 + header_length
    record = at + 4 + struct.unpack_from("<I", data, at)[0]  # the first record after the chunk
    assert data.index(b"op=\x04", record) < record + 64  # an index data record
    return record + 4 + struct.unpack_from("<I", data, record)[0]


@pytest.mark.parametrize(
    ("damage", "said"),
    [
        ("length", "an assertion in rosbags failed"),  # rosbags fails to open the bag
        # rosbags' assertion, or where, read chunk by chunk (this bag's chunks overlap in time).
        ("time", "an index entry does not match the message it points to: "),
        ("offset", "an index entry does not match the message it points to: "),
    ],
)
def test_a_ros1_bag_whose_index_entries_are_damaged_is_said_so_and_salvaged_whole(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    ros1_bags: dict[str, Path],
    damage: str,
    said: str,
) -> None:
    """Damaged index entries after a chunk made rosbags raise a bare AssertionError (when it
    opened the bag: a record's length that is not 12 bytes an entry; when it read the messages:
    an entry's time that is not its message's), said as `corrupt or truncated ... (AssertionError)`
    and a --salvage that `keeps the messages before the damage`: the bag's index is damaged, and
    --salvage, through the chunk infos, loses nothing."""
    import struct

    from rosbags.rosbag1 import Reader

    bag = ros1_bags["none"]
    data = bytearray(bag.read_bytes())
    entries = _first_index_entries(data, _chunk_infos(bag)[len(_chunk_infos(bag)) // 2][0])
    if damage == "length":
        struct.pack_into("<I", data, entries, struct.unpack_from("<I", data, entries)[0] + 12)
    else:
        at = entries + 4 + (4 if damage == "time" else 8)  # the first entry's nsec, or offset
        struct.pack_into("<I", data, at, struct.unpack_from("<I", data, at)[0] + 3)
    log = tmp_path / "in.bag"
    log.write_bytes(bytes(data))
    # What rosbags does with it: the bare assertion (or its own error, where the offset lands).
    expected = Exception if damage == "offset" else AssertionError
    with pytest.raises(expected), Reader(log) as reader:
        for _ in reader.messages():
            pass
    # (`info` reads the map topic only: an entry of a scan is not read; the index is, to open.)
    commands = [["process", log, "--no-output", "-q"], *([["info", log]] * (damage == "length"))]
    for command in commands:
        code, out, err = _run(capsys, *command)
        assert code == 1 and out == "", err
        assert err.startswith(f"error: {log}: the bag's index is damaged ({said}"), err
        assert err.endswith("); --salvage reads the bag chunk by chunk through its chunk infos\n")
        assert len(err.splitlines()) == 1 and "truncated" not in err
    code, _, err = _run(capsys, "process", log, "--no-output", "-q", "--salvage")
    assert code == 0, err
    assert _messages(log, salvage=True) == _messages(bag)  # every message, in rosbags' order
    assert log.read_bytes() == bytes(data)


def test_a_ros1_bag_whose_chunk_info_is_damaged_is_said_so_and_read_record_by_record(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bag: tuple[Path, list]
) -> None:
    """A chunk info record of a closed bag that does not read was `corrupt or truncated ROS 1
    bag, its index cannot be read (a recording that was not closed?)` with a --salvage that
    `keeps the messages before the damage`: it is the index that is damaged, and --salvage reads
    every record."""
    bag, _ = ros1_bag
    data = bytearray(bag.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    index_pos = int.from_bytes(data[at : at + 8], "little")
    at = data.index(b"start_time=", index_pos) + len(b"start_time")
    data[at] ^= 0xFF  # the first chunk info's start_time field loses its '='
    log = tmp_path / "in.bag"
    log.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", log, "--no-output", "-q")
    assert code == 1
    assert err == (
        f"error: {log}: the bag's index is damaged (a header field without '='); --salvage "
        "reads the bag record by record\n"
    )
    code, _, err = _run(capsys, "process", log, "--no-output", "-q", "--salvage")
    # Read record by record up to the damaged index: every message, but the index's counts cannot
    # vouch for it (exit 4).
    assert code == EXIT_SALVAGED, err
    assert _messages(log, salvage=True) == _in_file_order(bag)


def _damage_a_message_length(bag: Path, out: Path, flip: int) -> int:
    """A copy of ``bag`` (uncompressed chunks) with the data length of the first message record
    of its middle chunk xor ``flip`` (0x08: 8 bytes off); the chunk's position."""
    import struct

    data = bytearray(bag.read_bytes())
    chunks = _chunk_infos(bag)
    pos = chunks[len(chunks) // 2][0]
    content_at = pos + 4 + struct.unpack_from("<I", data, pos)[0] + 4
    entries = _index_data_after(data, pos)
    at = min(struct.unpack_from("<I", data, a)[0] for a, _, _ in entries)  # its first message
    length_at = content_at + at + 4 + struct.unpack_from("<I", data, content_at + at)[0]
    data[length_at] ^= flip
    out.write_bytes(bytes(data))
    return pos


def test_salvage_through_the_index_data_still_sees_a_damaged_record_length(
    tmp_path: Path, ros1_bags: dict[str, Path]
) -> None:
    """A flipped bit in a located message record's data length (an uncompressed chunk) gave that
    message cut short, with no loss said, once records were read where the index data points: the
    record after it must start where it ends, else the chunk is read record by record, which
    finds the damage, and it is skipped and said, as before."""
    bag = ros1_bags["none"]
    log = tmp_path / "in.bag"
    _damage_a_message_length(bag, log, 0x08)
    whole = {(t, bytes(d)) for t, _, d in _messages(bag)}
    with LogReader(log, salvage=True) as reader:
        kept = [(m.channel.topic, bytes(m.data)) for m in reader.messages()]
        assert any("skipped a damaged chunk" in loss for loss in reader.losses), reader.losses
    assert set(kept) <= whole  # nothing cut short


@pytest.mark.parametrize("flip", [0x08, 0xFF])
def test_a_damaged_message_record_length_is_an_error_not_a_message_cut_short(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bags: dict[str, Path], flip: int
) -> None:
    """A damaged data length of a message record (an uncompressed chunk, the index intact): read
    without --salvage, rosbags gave that message cut short (a map then skipped as malformed, a
    scan copied cut short into the output) and process exited 0, while --salvage said the chunk
    damaged. The record after it must start where it ends: an error naming the chunk."""
    bag = ros1_bags["none"]
    log = tmp_path / "in.bag"
    pos = _damage_a_message_length(bag, log, flip)
    whole = {(t, bytes(d)) for t, _, d in _messages(bag)}
    read = []
    with (
        pytest.raises(LogReadError, match=f"the chunk at byte {pos} of "),
        LogReader(log) as reader,
    ):
        read.extend((m.channel.topic, bytes(m.data)) for m in reader.messages())
    assert set(read) <= whole  # nothing cut short was handed out
    out = tmp_path / "out.bag"
    code, _, err = _run(capsys, "process", log, "-o", out, "-q")
    assert code == 1 and len(err.splitlines()) == 1 and not out.exists(), err
    assert err.startswith(f"error: {log}: the chunk at byte {pos} of "), err


def test_the_check_that_each_message_record_ends_where_the_next_starts_is_cheap(
    ros1_bags: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The check after every message rosbags reads (76a819b) parsed the next record's header into
    a dict of fields and took the chunk's size from a new buffer view each time: reading a bag of
    small messages took twice as long (300,000 of 4 bytes: 2.9 s for 1.4 s). It reads the op
    alone, each chunk's size once; and it still says what the fields would."""
    import struct

    from rose_logs.storage import ros1_stream, rosbags

    # rosbags' reading, whose check this is: this bag's chunks overlap in time, else read chunk
    # by chunk (which parses every message's header, as --salvage does).
    monkeypatch.setattr(rosbags, "MAX_OVERLAP_BYTES", 0)
    parsed = []
    fields = ros1_stream._fields
    monkeypatch.setattr(ros1_stream, "_fields", lambda block: parsed.append(1) or fields(block))
    read = len(_messages(ros1_bags["none"]))
    assert read and len(parsed) < read / 2, (len(parsed), read)

    def field(name: bytes, value: bytes) -> bytes:
        return struct.pack("<I", len(name) + 1 + len(value)) + name + b"=" + value

    for block in (
        field(b"op", b"\x02") + field(b"conn", b"\0\0\0\0"),
        field(b"conn", b"\0\0\0\0") + field(b"op", b"\x07"),
        field(b"op", b"\x02") + field(b"op", b"\x05"),  # the last one, as the fields' dict
        field(b"op", b"\x02\x02"),
        field(b"opx", b"\x02"),
        field(b"conn", b"1"),
        field(b"op", b"\x02") + b"\x01\x00",
        field(b"op", b"\x02") + struct.pack("<I", 9) + b"op",
        field(b"op", b"\x02") + struct.pack("<I", 2) + b"op",
        b"",
    ):
        try:
            expected: int | None = ros1_stream._op(fields(block))
        except ros1_stream._Damage:
            expected = None
        try:
            op: int | None = ros1_stream._header_op(block)
        except ros1_stream._Damage:
            op = None
        assert op == expected, block


@pytest.mark.parametrize("compression", ["none", "bz2"])
def test_salvage_reads_an_intact_ros1_bag_as_rosbags_orders_it(
    ros1_bags: dict[str, Path], compression: str
) -> None:
    """The salvaging reader reads the chunks itself: on an intact bag it gives what rosbags gives,
    in the same order, for every topic and for some."""
    bag = ros1_bags[compression]
    with LogReader(bag, salvage=True) as reader:
        salvaged = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        assert not reader.losses
        some = [m.log_time_ns for m in reader.messages(topics={"/map"})]
        assert not reader.losses
    assert salvaged == _messages(bag)
    with LogReader(bag) as reader:
        assert some == [m.log_time_ns for m in reader.messages(topics={"/map"})]


def test_info_on_a_ros1_bag_with_a_damaged_chunk_counts_what_it_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bags: dict[str, Path]
) -> None:
    """info --salvage printed the declared count of the map topic and no loss: it read one map of
    a bag that holds 14, stopping at a damaged chunk."""
    log = tmp_path / "in.bag"
    pos, _ = _damage_a_middle_chunk(ros1_bags["bz2"], log, "payload")
    with LogReader(ros1_bags["bz2"]) as reader:
        maps = sum(1 for _ in reader.messages(topics={"/map"}))
    code, out, err = _run(capsys, "info", log)
    assert code == 1 and out == "" and len(err.splitlines()) == 1
    assert f"the chunk at byte {pos} " in err and "--salvage" in err
    code, out, err = _run(capsys, "info", log, "--salvage")
    assert code == EXIT_SALVAGED, err
    assert "(declared)" in out and f"skipped a damaged chunk at byte {pos} " in out
    read = sum(topic == "/map" for topic, _, _ in _messages(log, salvage=True))
    # Every topic is read (as process --salvage reads them): the chunk's messages are counted.
    (said,) = [line for line in out.splitlines() if "messages the log declares" in line]
    if read < maps:  # the chunk held maps: the map topic is counted short
        assert f"/map {read} of {maps}" in said, out
    else:
        assert "/map " not in said, out


def _ros1_record(fields: dict[str, bytes], data: bytes) -> bytes:
    import struct

    header = b"".join(
        struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in fields.items()
    )
    return struct.pack("<I", len(header)) + header + struct.pack("<I", len(data)) + data


@pytest.fixture(scope="module")
def bz2_bomb() -> bytes:
    """A few hundred bytes of bz2 that expand to 600 MB (built without holding the 600 MB)."""
    import bz2

    packer = bz2.BZ2Compressor(9)
    block = bytes(1 << 20)
    return b"".join(packer.compress(block) for _ in range(600)) + packer.flush()


@pytest.mark.parametrize("declared", [1 << 31, 4096])
def test_a_bz2_bomb_in_a_salvaged_ros1_bag_never_expands_past_its_declared_size(
    tmp_path: Path, bz2_bomb: bytes, declared: int
) -> None:
    """Refused when the chunk declares more than any real chunk, cut at the declared size otherwise
    (then its records do not parse): one error line, and memory stays that of the program."""
    import struct
    import subprocess
    import sys

    bag = tmp_path / "bomb.bag.active"
    header = {"op": b"\x03", "index_pos": bytes(8), "conn_count": bytes(4), "chunk_count": bytes(4)}
    chunk = {"op": b"\x05", "compression": b"bz2", "size": struct.pack("<I", declared)}
    records = _ros1_record(header, b" " * 16) + _ros1_record(chunk, bz2_bomb)
    bag.write_bytes(b"#ROSBAG V2.0\n" + records)
    # VmHWM: the peak of this program's own memory (ru_maxrss would include the forking parent's).
    code = (
        "import re, sys; from rose_logs.cli import main; code = main(sys.argv[1:]); "
        "status = open('/proc/self/status').read(); "
        "print(int(re.search(r'VmHWM:\\s+(\\d+)', status).group(1)) // 1024); sys.exit(code)"
    )
    argv = ["process", str(bag), "--no-output", "-q", "--salvage"]
    run = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 1 and run.stderr.startswith(f"error: {bag}"), run.stderr
    assert int(run.stdout.split()[-1]) < 450  # MB; the bomb alone is 600


def test_a_ros1_bag_whose_header_misplaces_its_index_is_read_whole_and_loses_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bag: tuple[Path, list]
) -> None:
    bag, chunks = ros1_bag
    data = bytearray(bag.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = (chunks[1][0] + 10).to_bytes(8, "little")  # into a chunk
    odd = tmp_path / "odd.bag"
    odd.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", odd, "--no-output", "-q", "--salvage")
    assert code == 0, err  # a warning, but no message is lost
    assert "index is damaged or misplaced; every record was read" in err
    assert _messages(odd, salvage=True) == _in_file_order(bag)


@pytest.mark.parametrize("length", [0x40000000, 4096 + 1000, 100, 0])
def test_a_ros1_bag_whose_header_padding_length_is_damaged_is_salvaged_whole(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bag: tuple[Path, list], length: int
) -> None:
    """The data length of the bag header record (its padding) damaged, past the file, into the
    first chunk or short of it (inside the padding), the index and every chunk intact: --salvage said "--salvage reads the bag record
    by record" and exited 1. It reads the bag through its index and loses nothing; without
    --salvage, one error line."""
    import struct

    bag, _ = ros1_bag
    data = bytearray(bag.read_bytes())
    header_length = struct.unpack_from("<I", data, 13)[0]
    struct.pack_into("<I", data, 13 + 4 + header_length, length)
    odd = tmp_path / "odd.bag"
    odd.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", odd, "--no-output", "-q")
    assert code == 1 and len(err.splitlines()) == 1 and str(odd) in err, err
    code, _, err = _run(capsys, "process", odd, "--no-output", "-q", "--salvage")
    assert code == 0, err  # a warning, but no message is lost
    assert "read chunk by chunk through its chunk infos" in err
    assert _messages(odd, salvage=True) == _messages(bag)


@pytest.mark.parametrize(
    "damage",
    [
        "header_counts_fewer_chunks",
        "chunk_info_counts_none",
        "index_names_another_conn",
        "connection_record_renumbered",
    ],
)
def test_a_ros1_bag_whose_index_leaves_messages_out_is_damage_not_a_shorter_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros1_bag: tuple[Path, list], damage: str
) -> None:
    """rosbags reads what the index lists: a bag header counting fewer chunks than the file holds,
    a chunk info whose message count was zeroed, an index data record naming a connection
    that does not exist, or a connection record of the index whose id was damaged (rosbags
    drops the messages of the id the chunk infos count, a whole topic), lost those messages
    with exit 0."""
    import re

    bag, chunks = ros1_bag
    data = bytearray(bag.read_bytes())
    if damage == "header_counts_fewer_chunks":
        at = data.index(b"chunk_count=") + len(b"chunk_count=")
        data[at : at + 4] = (2).to_bytes(4, "little")
        lost = sum(n for _, n in chunks[2:])
        said = re.escape(
            f"{len(chunks) - 2} chunk(s) from byte {chunks[2][0]} on, with {lost} message(s), "
            "are not in the index"
        )
    elif damage == "chunk_info_counts_none":  # the last chunk info's count of connections
        at = data.rindex(b"count=") + len(b"count=")
        data[at : at + 4] = (0).to_bytes(4, "little")
        said = (
            rf"the chunk at byte {chunks[-1][0]} has index entries for {chunks[-1][1]} "
            r"message\(s\) \(connections [\d, ]+\), its chunk info counts 0 \(connections none\)"
        )
    elif damage == "connection_record_renumbered":  # the index's first connection record
        at = data.index(b"index_pos=") + len(b"index_pos=")
        index_pos = int.from_bytes(data[at : at + 8], "little")
        at = data.index(b"conn=", index_pos) + len(b"conn=")
        conn = int.from_bytes(data[at : at + 4], "little")
        data[at : at + 4] = (999).to_bytes(4, "little")
        from rosbags.rosbag1 import Reader

        with Reader(bag) as reader:
            lost = sum(c.connection_counts.get(conn, 0) for c in reader.chunk_infos)
        assert lost > 0
        said = (
            rf"its chunk infos count {lost} message\(s\) of connections {conn}, which it holds "
            r"no connection record of \(connections [\d, ]*999[\d, ]*\)"
        )
    else:  # the first index data record after the first chunk names connection 999
        at = data.index(b"conn=", data.index(b"op=\x04", chunks[0][0])) + len(b"conn=")
        data[at : at + 4] = (999).to_bytes(4, "little")
        said = (
            rf"the chunk at byte {chunks[0][0]} has index entries for {chunks[0][1]} "
            r"message\(s\) \(connections [\d, ]*999\), its chunk info counts "
            rf"{chunks[0][1]} \(connections [\d, ]+\)"
        )
    odd = tmp_path / "odd.bag"
    odd.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", odd, "--no-output", "-q")
    assert code == 1
    assert re.fullmatch(
        rf"error: {re.escape(str(odd))}: the bag's index is damaged \({said}\); --salvage reads "
        r"the bag record by record\n",
        err,
    ), err
    code, _, err = _run(capsys, "process", odd, "--no-output", "-q", "--salvage")
    assert code == 0, err  # every record read: nothing is lost
    assert _messages(odd, salvage=True) == _in_file_order(bag)


def _ros1_file(path: Path, chunk_records: bytes, *, compression: bytes = b"none") -> Path:
    """A never-closed ROS 1 bag: the bag header, then one chunk holding ``chunk_records``."""
    import struct

    header = {"op": b"\x03", "index_pos": bytes(8), "conn_count": bytes(4), "chunk_count": bytes(4)}
    chunk = {
        "op": b"\x05",
        "compression": compression,
        "size": struct.pack("<I", len(chunk_records)),
    }
    path.write_bytes(
        b"#ROSBAG V2.0\n" + _ros1_record(header, b" " * 16) + _ros1_record(chunk, chunk_records)
    )
    return path


def _connection_record(conn: int, topic: str) -> bytes:
    import struct

    info = {
        "topic": topic.encode(),
        "type": b"std_msgs/String",
        "md5sum": b"992ce8a1687cec8c8bd883ec73ca41d1",
    }
    fields = {"op": b"\x07", "conn": struct.pack("<I", conn), "topic": topic.encode()}
    body = b"".join(
        struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in info.items()
    )
    return _ros1_record(fields, body)


def _message_record(conn: int, sec: int) -> bytes:
    import struct

    fields = {"op": b"\x02", "conn": struct.pack("<I", conn), "time": struct.pack("<II", sec, 0)}
    return _ros1_record(fields, struct.pack("<I", 2) + b"hi")


def test_messages_whose_connection_record_is_missing_are_reported_not_dropped_silently(
    tmp_path: Path,
) -> None:
    records = _connection_record(0, "/a") + _message_record(0, 1) + _message_record(1, 2)
    bag = _ros1_file(tmp_path / "orphan.bag.active", records)
    with LogReader(bag, salvage=True) as reader:
        assert [c.topic for c in reader.channels] == ["/a"]
        assert len(list(reader.messages())) == 1
    assert "1 messages on 1 connections whose connection record is missing" in reader.losses[0]


def test_a_chunk_of_too_many_connections_is_damage_not_memory(tmp_path: Path) -> None:
    records = b"".join(_connection_record(i, f"/t{i}") for i in range(70_000))
    bag = _ros1_file(tmp_path / "many.bag.active", records)
    with pytest.raises(LogReadError, match="corrupt or truncated ROS 1 bag"):
        LogReader(bag, salvage=True).open()  # nothing before the damage: no channel at all


def test_a_record_longer_than_any_chunk_is_refused_before_it_is_read(tmp_path: Path) -> None:
    """A damaged length field may cover the rest of a huge file: not read into memory."""
    import struct

    from rose_logs.storage.ros1_stream import Ros1StreamReadBackend

    bag = tmp_path / "long.bag.active"
    header = {"op": b"\x03", "index_pos": bytes(8), "conn_count": bytes(4), "chunk_count": bytes(4)}
    chunk = {"op": b"\x05", "compression": b"none", "size": struct.pack("<I", 4096)}
    start = b"#ROSBAG V2.0\n" + _ros1_record(header, b" " * 16)
    fields = _ros1_record(chunk, b"")[:-4]  # the header, then a data length of 300 MiB
    with bag.open("wb") as out:
        out.write(start + fields + struct.pack("<I", 300 << 20))
        out.truncate(len(start) + len(fields) + 4 + (300 << 20))  # sparse: nothing to read for real
    backend = Ros1StreamReadBackend(bag)
    try:
        backend.open()
    finally:
        backend.close()
    assert "more than any chunk" in backend.damage and not backend.channels


def test_a_ros1_recording_still_growing_hands_out_what_was_counted(
    tmp_path: Path, ros1_bag: tuple[Path, list]
) -> None:
    from rose_logs.storage.ros1_stream import Ros1StreamReadBackend

    bag, chunks = ros1_bag
    data = bag.read_bytes()
    active = tmp_path / "s.bag.active"
    active.write_bytes(data[: chunks[2][0]])
    backend = Ros1StreamReadBackend(active)
    try:
        backend.open()
        declared = sum(c.message_count for c in backend.channels)
        with active.open("ab") as grows:  # the recorder writes one more chunk meanwhile
            grows.write(data[chunks[2][0] : chunks[3][0]])
        assert len(list(backend.messages(None))) == declared
    finally:
        backend.close()


def test_an_mcap_recording_still_growing_hands_out_what_was_counted(tmp_path: Path) -> None:
    from rose_logs.storage.mcap import McapStreamReadBackend

    whole = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    data = whole.read_bytes()
    log = tmp_path / "cut.mcap"
    log.write_bytes(data[: len(data) // 2])
    backend = McapStreamReadBackend(log)
    try:
        backend.open()
        declared = sum(c.message_count for c in backend.channels)
        with log.open("ab") as grows:
            grows.write(data[len(data) // 2 : len(data) * 3 // 4])
        assert len(list(backend.messages(None))) == declared
    finally:
        backend.close()


def test_metadata_type_disagreeing_with_storage_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "bag"
    write_session(log, "db3")
    meta = log / "metadata.yaml"
    meta.write_text(
        meta.read_text().replace("sensor_msgs/msg/LaserScan", "nav_msgs/msg/OccupancyGrid")
    )
    code, _, err = _run(capsys, "process", log, "--no-output", "-q")
    assert code == 1
    assert "metadata.yaml disagrees with the storage" in err and "/scan" in err


@pytest.mark.parametrize("fmt", ["db3", "mcap-dir"])
@pytest.mark.parametrize(
    "starting_time",
    [1_600_000_000_000_000_000, 10**23, -(10**20)],
)
def test_a_bag_folder_whose_metadata_misstates_its_start_reports_its_messages_times(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], starting_time: int, fmt: str
) -> None:
    """metadata.yaml's starting_time (with its duration) was taken for the bag's time range: one
    that lies gave a time range of 2020 for a recording of 2023 and snapshots at +100000005 s,
    one past the years a date can hold a traceback (info and process). The range is the one the
    storage holds (its first and last message), as for a bare storage file."""
    log = tmp_path / "bag"
    write_session(log, fmt)
    with LogReader(storage_file(log)) as reader:
        span = reader.start_ns, reader.end_ns
    meta = log / "metadata.yaml"
    text = meta.read_text()
    declared = f"nanoseconds_since_epoch: {span[0]}"
    assert declared in text
    meta.write_text(text.replace(declared, f"nanoseconds_since_epoch: {starting_time}"))
    with LogReader(log) as reader:
        assert (reader.start_ns, reader.end_ns) == span
    report = tmp_path / "r.json"
    code, _, err = _run(capsys, "process", log, "--no-output", "-q", "--json", report)
    assert code == 0, err
    data = json.loads(report.read_text())
    assert (data["start_ns"], data["end_ns"]) == span
    assert all(0 <= s["time_s"] <= (span[1] - span[0]) / 1e9 for s in data["snapshots"])
    code, out, err = _run(capsys, "info", log)
    assert code == 0 and "time range   2023-11-14 " in out, err


@pytest.mark.parametrize("which", [0, 1])
def test_a_split_bag_file_of_another_type_than_metadata_is_an_error_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], which: int
) -> None:
    """A bag split over two .db3 files, one of which stores /map as another type than
    metadata.yaml says: the storage's types were merged over the files, the later file's hiding
    the earlier's, so a first file of another type passed and rosbags skipped its maps, said as
    a damaged log ("read 1 of 3 messages the log declares"). Each file is checked, the error
    names it."""
    import sqlite3

    bag = tmp_path / "bag"
    files = _split_db3_bag(bag, "none")
    with contextlib.closing(sqlite3.connect(files[which])) as db:
        db.execute("UPDATE topics SET type = 'std_msgs/msg/String' WHERE name = '/map'")
        db.commit()
    for salvage in ([], ["--salvage"]):
        code, _, err = _run(capsys, "info", bag, *salvage)
        assert code == 1 and len(err.splitlines()) == 1, err
        assert err.startswith(f"error: {bag}: metadata.yaml disagrees with the storage (/map: ")
        assert f"the storage std_msgs/msg/String in {files[which].name})" in err, err


def test_a_split_bag_topic_listed_with_each_files_type_is_no_disagreement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A topic metadata.yaml lists twice, with the type of each file of a split bag that stores
    it: checked file by file against the topic's last type only, the first file would disagree."""
    import copy
    import sqlite3

    import yaml

    bag = tmp_path / "bag"
    files = _split_db3_bag(bag, "none")
    with contextlib.closing(sqlite3.connect(files[1])) as db:
        db.execute("UPDATE topics SET type = 'std_msgs/msg/String' WHERE name = '/map'")
        db.commit()
    meta = bag / "metadata.yaml"
    data = yaml.safe_load(meta.read_text())
    topics = data["rosbag2_bagfile_information"]["topics_with_message_count"]
    listed = next(t for t in topics if t["topic_metadata"]["name"] == "/map")
    other = copy.deepcopy(listed)  # (no YAML aliases: shared objects would be written as such)
    other["topic_metadata"]["type"] = "std_msgs/msg/String"
    other["topic_metadata"].pop("type_description_hash", None)
    listed["message_count"], other["message_count"] = 2, 1  # the maps of each file
    topics.append(other)
    meta.write_text(yaml.safe_dump(data))
    code, out, err = _run(capsys, "info", bag)
    assert code == 0 and "disagrees" not in err, err
    assert "nav_msgs/msg/OccupancyGrid, std_msgs/msg/String" in out


def test_info_counts_an_mcap_without_statistics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mcap.reader import make_reader
    from mcap.writer import Writer

    source, log = tmp_path / "s.mcap", tmp_path / "in.mcap"
    total = write_session(source, "mcap")
    with source.open("rb") as src, log.open("wb") as dst:
        reader = make_reader(src)
        summary = reader.get_summary()
        writer = Writer(dst, use_statistics=False)
        writer.start(profile="ros2", library="test")
        schemas = {
            i: writer.register_schema(s.name, s.encoding, s.data)
            for i, s in summary.schemas.items()
        }
        channels = {
            i: writer.register_channel(
                c.topic, c.message_encoding, schemas[c.schema_id], c.metadata
            )
            for i, c in summary.channels.items()
        }
        for _, channel, message in reader.iter_messages():
            writer.add_message(
                channels[channel.id], message.log_time, message.data, message.publish_time
            )
        writer.finish()
    code, out, _ = _run(capsys, "info", log)
    assert code == 0
    assert f"messages     {total}" in out


@pytest.mark.parametrize(
    "overrides",
    [
        {"resolution": 0.0},
        {"resolution": -1.0},
        {"resolution": 3e38},
        {"resolution": math.nan},
        {"position": (math.nan, 0.0, 0.0)},
        {"quaternion": (0.0, 0.0, 0.0, 0.0)},
        {"quaternion": (math.nan, 0.0, 0.0, 1.0)},
        {"stamp": (2**31 - 1, 1_500_000_000)},
    ],
    ids=["res0", "res-neg", "res-huge", "res-nan", "origin-nan", "quat0", "quat-nan", "nanosec"],
)
@pytest.mark.parametrize("fmt", ["mcap", "ros1"])
def test_garbage_map_messages_are_skipped_with_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], overrides: dict, fmt: str
) -> None:
    log = tmp_path / ("in.bag" if fmt == "ros1" else "in.mcap")
    write_session(log, fmt, maps=[{}, overrides, {}])
    report = tmp_path / "r.json"
    code, _, err = _run(capsys, "process", log, "--no-output", "--json", report, "-q")
    assert code == 0
    assert "copied unprocessed" in err
    data = json.loads(report.read_text())
    assert data["skipped_messages"] == 1 and len(data["snapshots"]) == 2


def test_a_fifo_is_refused_without_blocking(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    errors: list[BaseException] = []

    def read() -> None:
        try:
            LogReader(fifo)
        except LogReadError as err:
            errors.append(err)

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    thread.join(timeout=10)
    assert not thread.is_alive(), "blocked on a FIFO"
    assert errors and "not a regular file" in str(errors[0])


def test_json_to_stdout_moves_the_summary_to_stderr(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "in.mcap"
    write_session(log, "mcap")
    code, out, err = _run(capsys, "process", log, "--no-output", "--json", "-", "-q")
    assert code == 0
    assert json.loads(out)["message_count"] == 15
    assert "map topic" in err


def test_existing_json_report_needs_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "in.mcap"
    write_session(log, "mcap")
    report = tmp_path / "r.json"
    report.write_text("precious")
    code, _, err = _run(capsys, "process", log, "-o", tmp_path / "o.mcap", "--json", report, "-q")
    assert code == 1 and "exists already" in err
    assert report.read_text() == "precious"
    assert not (tmp_path / "o.mcap").exists()


def _mcap_bag_folder(folder: Path) -> Path:
    """The sample session as a ROS 2 bag folder of MCAP storage whose file is written as rosbag2
    writes it (zstd chunks with CRCs; rosbags writes them plain and unchecked); returns the file."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with LogReader(sample) as reader, Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as writer:  # fmt: skip
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store) for c in reader.channels}  # fmt: skip
        for m in reader.messages():
            writer.write(conns[m.channel.id], m.log_time_ns, bytes(m.data))
    storage = folder / f"{folder.name}.mcap"
    _write_as_rosbag2(storage, storage.read_bytes())
    return storage


def _write_as_rosbag2(
    storage: Path, plain: bytes, keep: Callable[[int], bool] = lambda _: True
) -> None:
    """Write the MCAP file ``plain`` (its messages whose log time is ``keep``) to ``storage`` as
    rosbag2 writes it: zstd chunks with CRCs, the same schema and channel ids."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType
    from mcap.writer import Writer as McapWriter

    source = make_reader(io.BytesIO(plain))
    summary = source.get_summary()
    assert summary is not None
    with storage.open("wb") as stream:
        writer = McapWriter(stream, compression=CompressionType.ZSTD, chunk_size=1 << 20)
        header = source.get_header()
        writer.start(profile=header.profile, library=header.library)
        schemas = {
            sid: writer.register_schema(s.name, s.encoding, s.data)
            for sid, s in sorted(summary.schemas.items())
        }
        channels = {
            cid: writer.register_channel(
                c.topic, c.message_encoding, schemas[c.schema_id], dict(c.metadata)
            )
            for cid, c in sorted(summary.channels.items())
        }
        # Same ids as rosbags gave them: metadata.yaml and the file agree.
        assert schemas == {k: k for k in schemas} and channels == {k: k for k in channels}
        for _, channel, message in source.iter_messages(log_time_order=False):
            if keep(message.log_time):
                writer.add_message(
                    channels[channel.id],
                    message.log_time,
                    message.data,
                    message.publish_time,
                    message.sequence,
                )
        writer.finish()


def _split_mcap_bag_folder(folder: Path) -> list[Path]:
    """The sample session as a ROS 2 bag folder of MCAP storage split in two files at half its
    time (rosbag2's --max-bag-duration), written as rosbag2 writes them; returns the files."""
    whole = _mcap_bag_folder(folder)
    plain = whole.read_bytes()
    whole.unlink()
    with LogReader(Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap") as reader:  # fmt: skip
        half = (reader.start_ns + reader.end_ns) // 2
    files = [folder / f"{folder.name}_0.mcap", folder / f"{folder.name}_1.mcap"]
    _write_as_rosbag2(files[0], plain, lambda t: t < half)
    _write_as_rosbag2(files[1], plain, lambda t: t >= half)
    meta = folder / "metadata.yaml"
    listed = "".join(f"  - {f.name}\n" for f in files)
    meta.write_text(meta.read_text().replace(f"  - {whole.name}\n", listed))
    return files


@pytest.mark.parametrize("damage", ["cut", "flipped"])
def test_salvage_reads_a_bag_folder_of_mcap_storage_as_its_bare_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], damage: str
) -> None:
    """A ROS 2 bag folder whose MCAP file was cut short read "corrupt or truncated log (File end
    magic is invalid.)", with or without --salvage (which kept nothing, nor said it could), and
    one with a damaged chunk lost every chunk after it: both now read as the bare file does,
    the cut one naming its file, the damaged chunk alone lost."""
    bag = tmp_path / "bag"
    storage = _mcap_bag_folder(bag)
    starts = _chunk_starts(storage)
    assert len(starts) >= 4
    data = bytearray(storage.read_bytes())
    if damage == "cut":
        data = data[: starts[3] + 100]
    else:
        data[starts[1] + 1_000] ^= 0xFF
    storage.write_bytes(bytes(data))
    bare = tmp_path / "bare.mcap"
    bare.write_bytes(bytes(data))
    results, errs = {}, {}
    for log in (bag, bare):
        out, report = tmp_path / f"o_{log.name}", tmp_path / f"r_{log.name}.json"
        refusal = "truncated MCAP file, cut short" if damage == "cut" else "corrupt"
        errs[log] = _refused_then_salvaged(capsys, log, out, report, refusal=refusal)
        assert "error:" not in errs[log]
        results[log] = json.loads(report.read_text())
    if damage == "cut":
        code, _, err = _run(capsys, "info", bag)
        assert code == 1 and err.startswith(f"error: {storage}: truncated MCAP file, cut short")
    else:
        assert f"{storage}: skipped a damaged chunk at byte {starts[1]} of" in errs[bag]
        # Without --salvage, the error names the damaged file, not the folder around it.
        code, _, err = _run(capsys, "process", bag, "-o", tmp_path / "o_again", "-q")
        assert code == 1 and err.startswith(f"error: {storage}: corrupt"), err
    folder, alone = results[bag], results[bare]
    assert 0 < folder["message_count"] == alone["message_count"] < 715
    assert len(folder["snapshots"]) == len(alone["snapshots"]) > 0
    assert folder["end_ns"] == alone["end_ns"]
    assert len(folder["losses"]) == len(alone["losses"])


@pytest.mark.parametrize(
    ("damaged", "damage"), [(0, "flipped"), (1, "flipped"), (1, "cut"), (1, "stub")]
)
def test_salvage_reads_each_file_of_a_split_mcap_bag_as_its_bare_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], damaged: int, damage: str
) -> None:
    """A bag split over two MCAP files, one with a damaged chunk or cut short: under --salvage a
    damaged chunk stopped the reading there (the rest of its file and every file after it
    lost), and a file cut short was refused with or without --salvage ("reads it on its own").
    Each file is now salvaged as it is on its own: the messages are the two bare files'
    salvaged, one file after the other, the losses name the damaged file, and the counts and
    end time are what was read. A file cut before its first message record ("stub") loses its
    messages, said naming it; the other file is read."""
    bag = tmp_path / "bag"
    files = _split_mcap_bag_folder(bag)
    target = files[damaged]
    starts = _chunk_starts(target)
    assert len(starts) >= 3
    data = bytearray(target.read_bytes())
    if damage == "cut":
        data = data[: starts[2] + 100]
    elif damage == "stub":
        data = data[:20]
    else:
        data[starts[1] + 1_000] ^= 0xFF
    target.write_bytes(bytes(data))
    expected = []
    for storage in files:
        if storage == target and damage == "stub":
            with pytest.raises(LogReadError), LogReader(storage, salvage=True):
                pass
            continue
        with LogReader(storage, salvage=True) as reader:
            expected += [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
    assert 0 < len(expected) < 715
    with LogReader(bag, salvage=True) as reader:
        read = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        losses = list(reader.losses)
    assert read == expected
    assert losses and any(loss.startswith(f"{target}: ") for loss in losses), losses
    other = files[1 - damaged]
    assert not any(str(other) in loss for loss in losses)
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q")
    assert code == 1 and len(err.splitlines()) == 1 and "--salvage" in err, err
    if damage != "flipped":  # cut short: the bag does not open, the error names the file
        assert err.startswith(f"error: {target}: truncated MCAP file (one of the bag's 2 files)")
    else:  # a damaged chunk: the error named the bag only, not the file of the two
        assert err.startswith(f"error: {target}: corrupt or truncated ("), err
        assert "one of the bag's 2 files; --salvage keeps what can be read of it" in err
    report = tmp_path / "r.json"
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q", "--salvage", "--json", report)
    assert code == EXIT_SALVAGED and "error:" not in err
    assert f"{target}: " in err
    salvaged = json.loads(report.read_text())
    assert salvaged["message_count"] == len(expected)
    assert salvaged["end_ns"] == max(t for _, t, _ in expected)
    assert len(salvaged["snapshots"]) == sum(1 for topic, _, _ in expected if topic == "/map")
    assert salvaged["losses"] == losses


def test_info_says_the_counts_of_a_split_mcap_bag_read_file_by_file_are_declared(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A split bag whose first file is cut short (read record by record) and whose second file
    has a damaged chunk (read through its index, which counts the chunk's messages): info
    --salvage printed the second file's declared counts and time range as if read ("messages
    462", the lost chunk's end as the end), while process's report said 360 messages; they are
    marked declared, as for a bag read through its index."""
    bag = tmp_path / "bag"
    first, second = _split_mcap_bag_folder(bag)
    first.write_bytes(first.read_bytes()[: first.stat().st_size // 2])
    data = bytearray(second.read_bytes())
    data[_chunk_starts(second)[-1] + 500] ^= 0xFF  # the last chunk of the second file
    second.write_bytes(bytes(data))
    with LogReader(bag, salvage=True) as reader:
        read = sum(1 for _ in reader.messages())
        assert reader.counts_declared and read < reader.message_count
    code, out, _ = _run(capsys, "info", bag, "--salvage")
    assert code == EXIT_SALVAGED and f"{second}: skipped a damaged chunk" in out
    lines = out.splitlines()
    assert next(line for line in lines if line.startswith("messages ")).endswith("(declared)")
    assert next(line for line in lines if line.startswith("time range ")).endswith("(declared)")
    # Both files cut short, both read record by record: the counts are what was read.
    second.write_bytes(second.read_bytes()[: second.stat().st_size // 2])
    with LogReader(bag, salvage=True) as reader:
        assert not reader.counts_declared
        assert sum(1 for _ in reader.messages()) == reader.message_count
    code, out, _ = _run(capsys, "info", bag, "--salvage")
    assert code == EXIT_SALVAGED and "(declared)" not in out


def test_a_damaged_chunk_of_a_split_mcap_bag_read_file_by_file_is_said_of_its_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A split bag read file by file (its second file's summary damaged: rosbags cannot open the
    bag, the file reads record by record, nothing lost) whose first file has a damaged chunk:
    without --salvage the error named the bag folder ("bag: corrupt or truncated log (crc
    validation failed in Chunk ...)"), not which of its files; it names the file."""
    bag = tmp_path / "bag"
    first, second = _split_mcap_bag_folder(bag)
    data = bytearray(second.read_bytes())
    data[_data_end(second) + 30] ^= 0xFF  # in its summary
    second.write_bytes(bytes(data))
    data = bytearray(first.read_bytes())
    data[_chunk_starts(first)[1] + 1_000] ^= 0xFF
    first.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q")
    assert code == 1 and err.splitlines()[-1].startswith(f"error: {first}: corrupt"), err
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q", "--salvage")
    assert code == EXIT_SALVAGED and f"{first}: skipped a damaged chunk" in err, err


def _without_chunks_damaged_part_way(path: Path, length: int | None = None) -> int:
    """Rewrite the MCAP file ``path`` without chunks (its messages in the data section, its
    summary intact) with the length of its middle message record damaged (``length``, else the
    file's: longer than the file): it opens through its summary and its reading fails part way,
    in no chunk a salvaging reader could skip. Returns the messages before the damage."""
    import struct

    from mcap.reader import make_reader
    from mcap.writer import Writer as McapWriter

    source = make_reader(io.BytesIO(path.read_bytes()))
    summary = source.get_summary()
    assert summary is not None
    out = io.BytesIO()
    writer = McapWriter(out, use_chunking=False)
    header = source.get_header()
    writer.start(profile=header.profile, library=header.library)
    for _, schema in sorted(summary.schemas.items()):
        writer.register_schema(schema.name, schema.encoding, schema.data)
    for _, channel in sorted(summary.channels.items()):
        writer.register_channel(
            channel.topic, channel.message_encoding, channel.schema_id, dict(channel.metadata)
        )
    starts = []
    for _, channel, message in source.iter_messages(log_time_order=True):
        starts.append(out.tell())
        writer.add_message(
            channel.id, message.log_time, message.data, message.publish_time, message.sequence
        )
    writer.finish()
    data = bytearray(out.getvalue())
    middle = len(starts) // 2
    assert data[starts[middle]] == 0x05  # a message record: opcode, then its length
    damaged = len(data) if length is None else length
    data[starts[middle] + 1 : starts[middle] + 9] = struct.pack("<Q", damaged)
    path.write_bytes(bytes(data))
    return middle


@pytest.mark.parametrize("other", ["intact", "summary", "cut"])
def test_salvage_reads_the_other_files_of_a_split_mcap_bag_one_of_which_fails_part_way(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], other: str
) -> None:
    """A split bag whose first file fails part way (a file without chunks whose middle record
    is damaged: no chunk to skip), its second intact (the bag opens in rosbags) or read file by
    file (its summary damaged, nothing lost; or cut short): --salvage stopped the whole merge
    there, the second file's messages lost unsaid (the loss named the bag, or said of the cut
    file "kept the 155 messages before it"). The first file's loss names it and the second
    file is read, in log-time order; without --salvage it is an error naming the first file."""
    bag = tmp_path / "bag"
    first, second = _split_mcap_bag_folder(bag)
    before = _without_chunks_damaged_part_way(first)
    data = bytearray(second.read_bytes())
    if other == "summary":  # rosbags cannot open the bag; the file reads record by record
        data[_data_end(second) + 30] ^= 0xFF
    elif other == "cut":
        data = data[: len(data) * 3 // 4]
    second.write_bytes(bytes(data))
    expected = []
    for storage in (first, second):
        with LogReader(storage, salvage=True) as reader:
            expected += [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
            assert reader.read_count == (before if storage == first else reader.message_count)
    with LogReader(bag, salvage=True) as reader:
        read = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        losses = list(reader.losses)
    assert read == expected and len(read) > before
    assert [t for _, t, _ in read] == sorted(t for _, t, _ in read)
    said = f"{first}: cannot be read past its first {before} messages ("
    assert any(loss.startswith(said) for loss in losses), losses
    assert all(loss.startswith((f"{first}: ", f"{second}: ", f"{bag}: read ")) for loss in losses)
    report = tmp_path / "r.json"
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q", "--salvage", "--json", report)
    assert code == EXIT_SALVAGED and "error:" not in err, err
    salvaged = json.loads(report.read_text())
    assert salvaged["message_count"] == len(read) and salvaged["losses"] == losses
    assert salvaged["end_ns"] == max(t for _, t, _ in read)
    code, out, _ = _run(capsys, "info", bag, "--salvage")
    assert code == EXIT_SALVAGED and f"{first}: cannot be read past its first " in out
    if other != "cut":  # (a file cut short is refused as it opens, naming that file)
        code, _, err = _run(capsys, "process", bag, "--no-output", "-q")
        (error,) = [line for line in err.splitlines() if not line.startswith("warning: ")]
        assert code == 1 and error.startswith(f"error: {first}: corrupt or truncated "), err
        assert "--salvage" in error


def test_a_record_length_damaged_to_terabytes_is_damage_not_memory_running_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A split bag whose first file's middle record claims 2**40 bytes: rosbags asks for them,
    and the MemoryError was said "out of memory (lower --max-cells?)", naming the folder. It is
    a corrupt file, named; --salvage reads around it."""
    bag = tmp_path / "bag"
    first, _ = _split_mcap_bag_folder(bag)
    _without_chunks_damaged_part_way(first, length=2**40)
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q")
    (error,) = [line for line in err.splitlines() if not line.startswith("warning: ")]
    assert code == 1 and error.startswith(f"error: {first}: corrupt or truncated "), err
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q", "--salvage")
    assert code == EXIT_SALVAGED and f"{first}: cannot be read past its first " in err, err


@pytest.mark.parametrize("storage", ["mcap", "db3"])
def test_a_split_bag_whose_files_are_listed_out_of_time_order_reads_in_log_time_order(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], storage: str
) -> None:
    """A split bag whose metadata.yaml lists its later file first (or whose files overlap in
    time) came out file after file, as rosbags reads it: not in log-time order, the session's
    map snapshots out of order ("time range +35.0 s .. +30.0 s", a break found where there is
    none). The files are merged by log time, intact or salvaged file by file."""
    bag = tmp_path / "bag"
    if storage == "mcap":
        files = _split_mcap_bag_folder(bag)
        sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
        with LogReader(sample) as reader:
            expected = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
    else:
        files = _split_db3_bag(bag, "none")
        with LogReader(bag) as reader:
            expected = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
    meta = bag / "metadata.yaml"
    listed = "".join(f"  - {f.name}\n" for f in files)
    meta.write_text(
        meta.read_text().replace(listed, "".join(f"  - {f.name}\n" for f in files[::-1]))
    )
    for salvage in (False, True):
        with LogReader(bag, salvage=salvage) as reader:
            read = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
            assert read == expected and not reader.losses
    if storage == "mcap":
        code, out, _ = _run(capsys, "process", bag, "--no-output")
        assert code == 0 and "time range   +5.0 s .. +70.0 s" in out and "break        none" in out
        # The later file (listed first) cut short: read on its own, merged with the other.
        files[1].write_bytes(files[1].read_bytes()[: files[1].stat().st_size // 2])
        with LogReader(bag, salvage=True) as reader:
            times = [m.log_time_ns for m in reader.messages()]
            assert reader.losses and times == sorted(times) and len(times) < len(expected)
    else:
        first = files[0].read_bytes()
        for page in range(2, len(first) // 4096):  # a page of the earlier file no longer reads
            data = bytearray(first)
            data[page * 4096] = 0x77
            files[0].write_bytes(bytes(data))
            with LogReader(bag, salvage=True) as reader:
                times = [m.log_time_ns for m in reader.messages()]
                assert times == sorted(times)


def _split_db3_bag(bag: Path, damage: str = "page") -> list[Path]:
    """A session as a ROS 2 bag folder of SQLite storage split in two files at its middle
    message (as rosbag2 splits one), its first file damaged: a B-tree page of it no longer
    reads, after some of its messages do ("page"), or its header, so that it does not open
    ("header"), or left intact ("none"). Returns the two files."""
    import sqlite3

    write_session(bag, "db3")
    first = storage_file(bag)
    second = bag / f"{bag.name}_1.db3"
    shutil.copy(first, second)
    with contextlib.closing(sqlite3.connect(first)) as db:
        times = [t for (t,) in db.execute("SELECT timestamp FROM messages ORDER BY timestamp")]
    middle = times[len(times) // 2]
    for storage, keep in ((first, "timestamp < ?"), (second, "timestamp >= ?")):
        with contextlib.closing(sqlite3.connect(storage)) as db:
            db.execute(f"DELETE FROM messages WHERE NOT ({keep})", (middle,))
            db.commit()
            db.execute("VACUUM")
    meta = bag / "metadata.yaml"
    listed = f"  - {first.name}\n"
    meta.write_text(meta.read_text().replace(listed, f"{listed}  - {second.name}\n"))
    intact = first.read_bytes()
    if damage == "none":
        return [first, second]
    if damage == "header":
        first.write_bytes(b"no SQLite file.\0" + intact[16:])
        return [first, second]
    for page in range(2, len(intact) // 4096):  # the first page that fails part way
        data = bytearray(intact)
        data[page * 4096] = 0x77  # its page type: no B-tree page
        first.write_bytes(bytes(data))
        read = 0
        try:
            with LogReader(first) as reader:
                for _ in reader.messages():
                    read += 1
        except LogReadError:
            if read:
                return [first, second]
    pytest.fail("no page of the first file fails part way")


def test_salvage_reads_the_files_after_a_damaged_one_of_a_split_sqlite_bag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bag split over two .db3 files whose first is damaged part way: --salvage stopped the
    reading there, the second file lost too, and the loss named the bag, not the file. The
    first file's messages before the damage are kept (as of the file on its own), the second
    file is read, the loss names the first file, and the counts say what was read."""
    bag = tmp_path / "bag"
    first, second = _split_db3_bag(bag)
    expected = []
    for storage in (first, second):
        with LogReader(storage, salvage=True) as reader:
            expected += [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
    with LogReader(second) as reader:
        assert reader.message_count and reader.read_count == 0
        in_second = reader.message_count
    with LogReader(bag, salvage=True) as reader:
        read = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        losses = list(reader.losses)
    assert read == expected and in_second < len(read) < 15
    assert losses[0].startswith(f"{first}: cannot be read past its first "), losses
    assert "the bag's other files are read" in losses[0]
    assert not any(str(second) in loss for loss in losses)
    assert (
        losses[1]
        == f"{bag}: read {len(read)} of 15 messages the log declares"
        + losses[1].split("declares", 1)[1]
    )
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q")  # the error names the file
    assert code == 1 and len(err.splitlines()) == 1, err
    assert (
        err.startswith(f"error: {first}: corrupt or truncated (") and "of the bag's 2 files" in err
    )
    report = tmp_path / "r.json"
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q", "--salvage", "--json", report)
    assert code == EXIT_SALVAGED and "error:" not in err
    salvaged = json.loads(report.read_text())
    assert salvaged["message_count"] == len(read)
    assert salvaged["end_ns"] == max(t for _, t, _ in read)
    assert salvaged["losses"] == losses


@pytest.mark.parametrize("damage", ["page", "header"])
def test_info_salvage_counts_every_topic_a_split_bag_lost(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], damage: str
) -> None:
    """A split bag whose first file is read part way (or does not open): info --salvage read
    the map topics only, and its losses counted theirs alone ("read 2 of 3 messages the log
    declares (/map 2 of 3)", "cannot be read past its first 1 messages") while the file's /scan
    messages were lost too, unsaid. It reads every topic, as process --salvage does, and says
    the same losses."""
    bag = tmp_path / "bag"
    _split_db3_bag(bag, damage)
    report = tmp_path / "r.json"
    code, _, _ = _run(capsys, "process", bag, "--no-output", "-q", "--salvage", "--json", report)
    losses = json.loads(report.read_text())["losses"]
    assert code == EXIT_SALVAGED and any("/scan " in loss for loss in losses), losses
    code, out, _ = _run(capsys, "info", bag, "--salvage")
    assert code == EXIT_SALVAGED
    said = out.split("\nlosses       ", 1)[1].splitlines()
    assert [line.strip() for line in said] == losses
    assert "messages     15 (declared)" in out  # the counts stay as declared
    code, out, _ = _run(capsys, "info", bag)  # (without --salvage: one error line)
    assert code == 1 and out == ""


def test_salvage_reads_the_other_files_of_a_split_sqlite_bag_one_of_which_does_not_open(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bag split over two .db3 files whose first does not open (its header damaged): the
    whole bag was refused, with or without --salvage, the error naming the bag. The error
    names the file and what --salvage reads; --salvage reads the other file, the loss naming
    the one that does not open."""
    bag = tmp_path / "bag"
    first, second = _split_db3_bag(bag, "header")
    with LogReader(second) as reader:
        expected = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q")
    assert code == 1 and len(err.splitlines()) == 1, err
    assert err.startswith(f"error: {first}: cannot be opened (")
    assert err.rstrip().endswith("one of the bag's 2 files; --salvage reads the others")
    with LogReader(bag, salvage=True) as reader:
        read = [(m.channel.topic, m.log_time_ns, bytes(m.data)) for m in reader.messages()]
        losses = list(reader.losses)
    assert read == expected and 0 < len(read) < 15
    assert losses[0].startswith(f"{first}: cannot be opened (")
    assert losses[0].endswith("none of its messages are read, the bag's other files are")
    assert losses[1].startswith(f"{bag}: read {len(read)} of 15 messages the log declares")
    assert len(losses) == 2 and not any(str(second) in loss for loss in losses)
    report = tmp_path / "r.json"
    code, _, err = _run(capsys, "process", bag, "--no-output", "-q", "--salvage", "--json", report)
    assert code == EXIT_SALVAGED and "error:" not in err
    salvaged = json.loads(report.read_text())
    assert salvaged["message_count"] == len(read) and salvaged["losses"] == losses
    assert salvaged["end_ns"] == max(t for _, t, _ in read)
    # Neither file opens: nothing to read, the first error stands (with or without --salvage).
    second.write_bytes(first.read_bytes())
    for salvage in ([], ["--salvage"]):
        code, _, err = _run(capsys, "process", bag, "--no-output", "-q", *salvage)
        assert code == 1 and len(err.splitlines()) == 1 and "corrupt or truncated log" in err


def test_salvage_reads_an_intact_mcap_bag_folder_as_without_it(tmp_path: Path) -> None:
    """--salvage reads a bag folder of one MCAP file through the file's index (past damaged
    chunks): on an intact bag, the same messages, channels and order as rosbags reads them."""
    bag = tmp_path / "bag"
    _mcap_bag_folder(bag)
    read = []
    for salvage in (False, True):
        with LogReader(bag, salvage=salvage) as reader:
            read.append(
                [
                    (m.channel.id, m.channel.topic, m.log_time_ns, m.publish_time_ns, bytes(m.data))
                    for m in reader.messages()
                ]
            )
            assert not reader.losses
    assert len(read[0]) == 715 and read[0] == read[1]


def test_salvage_reads_an_mcap_bag_folder_of_compressed_messages_as_without_it(
    tmp_path: Path,
) -> None:
    """A bag folder whose MCAP file holds each message zstd-compressed (rosbag2's compression
    mode "message": the file is a plain .mcap) was read under --salvage through the bare file,
    whose messages are the compressed bytes: every message came out as zstd data. It is read
    by rosbags, which decompresses them, as without --salvage."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path / "bag"
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with LogReader(sample) as reader, writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store) for c in reader.channels}  # fmt: skip
        for m in reader.messages():
            writer.write(conns[m.channel.id], m.log_time_ns, bytes(m.data))
    assert (bag / "bag.mcap").is_file()
    read = _read_alike_with_and_without_salvage(bag)
    assert len(read) == 715


@pytest.mark.parametrize("listed", ["extra", "only"])
def test_an_mcap_bag_folder_missing_a_listed_file_says_it_is_missing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], listed: str
) -> None:
    """metadata.yaml lists an MCAP file that is not there: rosbags' "Some database files are
    missing" was replaced by "MCAP file corrupt ([Errno 2] No such file ...)", with or without
    --salvage, offering --salvage on the file that does not exist."""
    bag = tmp_path / "bag"
    _mcap_bag_folder(bag)
    meta = bag / "metadata.yaml"
    if listed == "extra":
        text = meta.read_text().replace("  - bag.mcap\n", "  - bag.mcap\n  - bag_1.mcap\n")
    else:
        text = meta.read_text().replace("  - bag.mcap\n", "  - gone.mcap\n")
    meta.write_text(text)
    for salvage in ([], ["--salvage"]):
        code, _, err = _run(capsys, "process", bag, "--no-output", "-q", *salvage)
        assert code == 1 and len(err.splitlines()) == 1, err
        assert "missing" in err and "corrupt" not in err.replace("corrupt or truncated log", "")
        assert "No such file" not in err and "reads it on its own" not in err


def test_salvage_keeps_the_channels_of_one_topic_offered_with_two_qos(tmp_path: Path) -> None:
    """Two channels of one topic and type offered with different QoS (two publishers): --salvage
    mapped the MCAP file's channels to the bag's by topic and type alone, so every message went
    to the last of them, and the counts' check called the intact bag damaged. They are mapped as
    rosbags maps them (topic, type and QoS)."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    store = get_typestore(Stores.ROS2_HUMBLE)
    never = QosTime(0, 0)
    qos = [
        Qos(
            QosHistory.KEEP_LAST,
            depth,
            reliability,
            durability,
            never,
            never,
            QosLiveliness.AUTOMATIC,
            never,
            False,
        )
        for depth, reliability, durability in (
            (1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL),
            (10, QosReliability.BEST_EFFORT, QosDurability.VOLATILE),
        )
    ]
    bag = tmp_path / "bag"
    with LogReader(sample) as reader, Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:  # fmt: skip
        conns = {
            c.id: [
                writer.add_connection(c.topic, c.msgtype, typestore=store, offered_qos_profiles=[q])
                for q in qos
            ]
            for c in reader.channels
        }
        for i, m in enumerate(reader.messages()):
            writer.write(conns[m.channel.id][i % 2], m.log_time_ns, bytes(m.data))
    read = _read_alike_with_and_without_salvage(bag)
    assert len(read) == 715
    assert len({channel for channel, _, _ in read}) == 4


def _read_alike_with_and_without_salvage(bag: Path) -> list[tuple[int, int, bytes]]:
    """``bag``'s messages (channel id, log time, data), read the same with and without
    ``--salvage`` and with no loss said."""
    read = []
    for salvage in (False, True):
        with LogReader(bag, salvage=salvage) as reader:
            read.append([(m.channel.id, m.log_time_ns, bytes(m.data)) for m in reader.messages()])
            assert not reader.losses
    assert read[0] == read[1]
    return read[0]


def test_an_io_error_under_overlapping_ros1_chunks_is_no_damage(
    tmp_path: Path,
    ros1_bags: dict[str, Path],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """This bag's chunks overlap in time, so it is read chunk by chunk: an EIO of the disk under
    a chunk came out of the reader as a bare ValueError, a traceback (rosbags' reading said it
    in one line). One line naming the file and the I/O error, exit 1, no output."""
    import errno

    from rose_logs.storage import ros1_stream

    def failing_disk(*_: object, **__: object) -> bytes:
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(ros1_stream, "_decompress", failing_disk)  # where a chunk's data is read
    bag, out = ros1_bags["none"], tmp_path / "o.bag"
    code, _, err = _run(capsys, "process", bag, "-o", out, "-q")
    assert (code, err) == (1, f"error: {bag}: Input/output error\n")
    assert not out.exists()
