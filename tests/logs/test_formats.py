"""rose_logs.formats: a log's format from its content, and the format an output name implies."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import FORMATS, MapMsg, build_log, log_path

from rose_logs.errors import LogReadError
from rose_logs.formats import FORMATS as LOG_FORMATS
from rose_logs.formats import detect_format, format_from_path


@pytest.mark.parametrize("kind", ["ros1", "ros1-bz2", "db3", "mcap-dir", "mcap-ros2", "mcap-ros1"])
def test_detects_every_format_written_by_other_libraries(tmp_path: Path, kind: str) -> None:
    import numpy as np

    grid = np.zeros((4, 5), dtype=np.int8)
    built = build_log(log_path(tmp_path, kind), kind, [MapMsg(10**18, grid)], scans_per_map=0)
    expected = FORMATS[kind][0]
    assert detect_format(built.path) == expected
    assert expected in LOG_FORMATS
    if kind in ("db3", "mcap-dir"):
        # The storage file inside a ROS 2 bag folder is recognised on its own too.
        (storage,) = [p for p in built.path.iterdir() if p.suffix in (".db3", ".mcap")]
        assert detect_format(storage) == ("db3" if kind == "db3" else "mcap")


def test_content_decides_not_the_name(tmp_path: Path) -> None:
    import numpy as np

    built = build_log(tmp_path / "x.mcap", "mcap-ros2", [MapMsg(10**18, np.zeros((2, 2), np.int8))])
    renamed = built.path.rename(tmp_path / "misnamed.bag")
    assert detect_format(renamed) == "mcap"


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (b"", "empty file"),
        (b"#ROSBAG V1.2\n", "unrecognised header"),  # ROS 1 bag version 1.2: unsupported
        (b"hello, world", "unrecognised header"),
        (b"\x89MCAP", "unrecognised header"),  # truncated magic
    ],
)
def test_unsupported_files_are_one_line_errors(
    tmp_path: Path, content: bytes, problem: str
) -> None:
    path = tmp_path / "run.bag"
    path.write_bytes(content)
    with pytest.raises(LogReadError, match=problem) as info:
        detect_format(path)
    assert str(info.value).startswith(f"{path}: not a ROS 1 bag, ROS 2 bag or MCAP file")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name", ["aces.log", "aces.log.gz", "intel.clf", "lines.txt"])
def test_a_carmen_log_given_as_a_recording_points_to_convert(tmp_path: Path, name: str) -> None:
    """The README's own examples use CARMEN logs: processing one said only 'unrecognised header'."""
    path = tmp_path / name
    path.write_bytes(b"FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    with pytest.raises(
        LogReadError, match="a CARMEN laser log becomes a session with 'rose-bag convert'"
    ):
        detect_format(path)


def test_missing_paths_and_folders_without_metadata(tmp_path: Path) -> None:
    with pytest.raises(LogReadError, match="no such file or directory"):
        detect_format(tmp_path / "nothing.mcap")
    (tmp_path / "folder").mkdir()
    with pytest.raises(LogReadError, match=r"folder without metadata\.yaml"):
        detect_format(tmp_path / "folder")


def test_bag_folder_storage_comes_from_metadata(tmp_path: Path) -> None:
    folder = tmp_path / "bag"
    folder.mkdir()
    (folder / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  storage_identifier: mcap\n"
    )
    assert detect_format(folder) == "mcap-dir"
    (folder / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n"
    )
    assert detect_format(folder) == "db3"


@pytest.mark.parametrize(
    ("field", "said"),
    [
        ("  version: nine\n", "version should be an integer, not 'nine'"),
        (
            "  starting_time:\n    nanoseconds_since_epoch: abc\n",
            "starting_time.nanoseconds_since_epoch should be an integer, not 'abc'",
        ),
        (
            "  relative_file_paths: x.db3\n",
            "relative_file_paths should be a list of file names, not 'x.db3'",
        ),
        ("  relative_file_paths: [1]\n", "relative_file_paths should be a list of file names"),
        ("  message_count: true\n", "message_count should be an integer, not True"),
    ],
)
def test_metadata_fields_of_the_wrong_type_are_named(tmp_path: Path, field: str, said: str) -> None:
    """rosbags said "'>' not supported between instances of 'str' and 'int'" or "can only
    concatenate str (not "int") to str"."""
    folder = tmp_path / "bag"
    folder.mkdir()
    (folder / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n" + field
    )
    with pytest.raises(LogReadError) as info:
        detect_format(folder)
    assert str(info.value) == f"{folder / 'metadata.yaml'}: {said}"


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("out.bag", "ros1"),
        ("out.BAG", "ros1"),
        ("out.mcap", "mcap"),
        ("dir/out.Mcap", "mcap"),
        ("out.db3", "db3"),
        ("out", None),
        ("out.bag.tmp", None),
        ("out.rrd", None),
        ("archive.mcap.zst", None),
    ],
)
def test_format_from_output_name(name: str, expected: str | None) -> None:
    assert format_from_path(Path(name)) == expected


def _without_summary(source: Path, target: Path, *, reverse: bool) -> None:
    """Rewrite a bare MCAP file with no summary section (optional in MCAP), messages reversed."""
    from mcap.reader import make_reader
    from mcap.writer import IndexType, Writer

    with source.open("rb") as f:
        reader = make_reader(f)
        profile = reader.get_header().profile
        messages = list(reader.iter_messages(log_time_order=True))
    if reverse:
        messages.reverse()
    with target.open("wb") as f:
        writer = Writer(
            f,
            use_summary_offsets=False,
            use_statistics=False,
            index_types=IndexType.NONE,
            repeat_channels=False,
            repeat_schemas=False,
        )
        writer.start(profile=profile, library="tests")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in messages:
            if channel.id not in channels:
                if schema.id not in schemas:
                    schemas[schema.id] = writer.register_schema(
                        schema.name, schema.encoding, schema.data
                    )
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], channel.metadata
                )
            writer.add_message(
                channels[channel.id],
                message.log_time,
                message.data,
                message.publish_time,
                message.sequence,
            )
        writer.finish()


@pytest.mark.parametrize("reverse", [False, True], ids=["in-order", "out-of-order"])
def test_a_complete_mcap_without_summary_reads_like_one_with_it(
    tmp_path: Path, fr079, reverse: bool
) -> None:
    """The summary section is optional in MCAP: such a file is no truncated recording, and its
    messages come in log-time order even when written out of order."""
    from conftest import read_all, session_maps

    from rose_logs.reader import LogReader

    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:3]))
    bare = tmp_path / "bare.mcap"
    _without_summary(built.path, bare, reverse=reverse)
    with LogReader(bare) as reader:
        assert reader.losses == []
        times = [m.log_time_ns for m in reader.messages()]
    assert times == sorted(times)
    assert read_all(bare) == read_all(built.path)
    # Truncated, it is still refused (a recording cut off), naming --salvage.
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bare.read_bytes()[: bare.stat().st_size // 2])
    with pytest.raises(LogReadError, match="salvage"):
        LogReader(cut).open()


def test_a_summaryless_mcap_without_its_closing_magic_loses_nothing(tmp_path: Path, fr079) -> None:
    from conftest import read_all, session_maps

    from rose_logs.reader import LogReader

    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:3]))
    bare = tmp_path / "bare.mcap"
    _without_summary(built.path, bare, reverse=False)
    no_magic = tmp_path / "no_magic.mcap"
    no_magic.write_bytes(bare.read_bytes()[:-8])
    with LogReader(no_magic) as reader:
        assert reader.losses == []
    assert read_all(no_magic) == read_all(built.path)


def _summary_start(data: bytearray) -> int:
    """Offset of an MCAP file's summary section (from its footer)."""
    import struct

    return struct.unpack_from("<Q", data, len(data) - 8 - 4 - 16)[0]


def _summary_record(data: bytearray, opcode: int) -> int:
    """Offset of the first record of type ``opcode`` in an MCAP file's summary section."""
    import struct

    at = _summary_start(data)
    while data[at] != opcode:
        at += 9 + struct.unpack_from("<Q", data, at + 1)[0]  # opcode, length, content
    return at


# Where a byte of the summary is damaged: a channel's count in the Statistics record (after its
# opcode and length, 42 bytes of totals and times, the map's byte length and the channel id); a
# letter of a topic in a Channel record (id, then the topic's length and text); the high byte of
# the first summary record's length (the summary no longer reads at all).
_SUMMARY_DAMAGE = {
    "count": lambda data: _summary_record(data, 0x0B) + 9 + 42 + 4 + 2,
    "topic": lambda data: _summary_record(data, 0x04) + 9 + 2 + 4 + 1,
    "length": lambda data: _summary_start(data) + 8,
}


def test_an_mcap_without_its_closing_magic_is_not_called_damaged(
    tmp_path: Path, fr079, caplog: pytest.LogCaptureFixture
) -> None:
    """Without its last 8 bytes the footer is not where the summary CRC's check looks: no false
    'damaged' warning, and every message reads."""
    from conftest import read_all, session_maps

    from rose_logs.reader import LogReader

    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:3]))
    cut = tmp_path / "no_magic.mcap"
    cut.write_bytes(built.path.read_bytes()[:-8])
    with caplog.at_level("INFO"), LogReader(cut) as reader:
        assert reader.losses == []
    assert "damaged" not in caplog.text
    assert read_all(cut) == read_all(built.path)


@pytest.mark.parametrize("where", sorted(_SUMMARY_DAMAGE))
def test_a_damaged_mcap_summary_is_seen_and_read_around(
    tmp_path: Path, fr079, caplog: pytest.LogCaptureFixture, where: str
) -> None:
    """The footer's CRC of the summary section (which the mcap package does not check) tells a
    damaged index from a file whose counts are wrong: the file is read record by record, its
    definitions from the data section, with a warning, and no message is lost."""
    from conftest import read_all, session_maps

    from rose_logs.reader import LogReader

    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:3]))
    with LogReader(built.path) as reader:
        counts = {c.topic: c.message_count for c in reader.channels}
    data = bytearray(built.path.read_bytes())
    data[_SUMMARY_DAMAGE[where](data)] ^= 1
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    with caplog.at_level("WARNING"), LogReader(damaged) as reader:
        assert {c.topic: c.message_count for c in reader.channels} == counts
        assert reader.losses == []
    assert "summary section (index, channels, counts) damaged" in caplog.text
    assert read_all(damaged) == read_all(built.path)


def test_bytes_inserted_in_an_mcap_name_the_file_and_salvage_keeps_the_start(
    tmp_path: Path,
) -> None:
    """Bytes inserted in the data section move the summary away from where the footer points:
    its CRC fails, and record by record the file does not read to its end either. The error was
    the CRC's alone, naming no file and no remedy (also under --salvage); now it names the file,
    and --salvage keeps the messages before the damage."""
    from mcap.reader import make_reader

    from rose_logs.reader import LogReader

    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    with sample.open("rb") as stream:
        chunks = make_reader(stream).get_summary().chunk_indexes
    assert len(chunks) > 1
    last = max(chunk.chunk_start_offset for chunk in chunks)  # before the last chunk
    data = bytearray(sample.read_bytes())
    data[last:last] = data[last : last + 100]
    damaged = tmp_path / "inserted.mcap"
    damaged.write_bytes(bytes(data))
    with pytest.raises(LogReadError) as raised, LogReader(damaged):
        pass
    said = str(raised.value)
    assert said.startswith(f"{damaged}: ") and "--salvage" in said and "\n" not in said
    with LogReader(damaged, salvage=True) as reader:
        assert len(reader.losses) == 1 and reader.losses[0].startswith(f"{damaged}: ")
        times = [m.log_time_ns for m in reader.messages()]
    with LogReader(sample) as reader:
        whole = [m.log_time_ns for m in reader.messages()]
    assert 0 < len(times) < len(whole)
    assert times == whole[: len(times)]


def test_salvage_too_large_to_sort_keeps_every_message_in_file_order(
    tmp_path: Path, fr079, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past the sorting cap a damaged file keeps what it has, in file order (it kept nothing);
    a complete one is refused, naming ``mcap recover``."""
    from conftest import session_maps

    from rose_logs.reader import LogReader
    from rose_logs.storage import mcap

    monkeypatch.setattr(mcap, "MAX_SORTED_BYTES", 100)
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:3]))
    bare = tmp_path / "bare.mcap"
    _without_summary(built.path, bare, reverse=True)
    with pytest.raises(LogReadError, match="mcap recover"), LogReader(bare) as reader:
        list(reader.messages())
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bare.read_bytes()[:-40])  # the footer gone: damaged
    with LogReader(cut, salvage=True) as reader:
        times = [m.log_time_ns for m in reader.messages()]
        assert "in file order" in reader.losses[0]
    with LogReader(built.path) as whole:
        assert len(times) == whole.message_count
    assert times == sorted(times, reverse=True)


def test_one_topic_name_reads_that_topic(tmp_path: Path, fr079) -> None:
    """``messages(topics="/map")``: one name is one topic (it was read as the one-character topics
    "/", "m", "a", "p": no message, no error)."""
    from conftest import START_NS

    from rose_logs.reader import LogReader

    maps = [MapMsg(START_NS + i * 1_000_000_000, grid) for i, grid in enumerate(fr079[:3], 1)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    with LogReader(built.path) as reader:
        by_name = [m.log_time_ns for m in reader.messages(topics="/map")]
        by_list = [m.log_time_ns for m in reader.messages(topics=["/map"])]
    assert by_name == by_list == [m.t_ns for m in maps]
    from rose_logs.session import process_log

    assert len(process_log(built.path, topics="/map").records) == len(maps)
