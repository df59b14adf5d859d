"""Bare MCAP files (ros1 or ros2 profile) through the ``mcap`` package: reading and writing."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import heapq
import io
import itertools
import logging
import os
import struct
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from rose.limits import short
from rose.threads import threads_in_this_context
from rose_logs.errors import LogReadError, as_memory_error, reraise_unless_damage
from rose_logs.formats import MCAP_MAGIC
from rose_logs.storage.base import WriteBackend
from rose_logs.storage.connections import (
    KnownDefinitions,
    QosStyle,
    default_qos,
    offered_qos,
    qos_style,
    qos_yaml,
    warn_no_definition,
)
from rose_logs.storage.records import (
    Channel,
    RawMessage,
    merged_by_log_time,
    normalize_msgtype,
    parse_latching,
    read_at,
    read_part_way,
    ros1_msgtype,
)

__all__ = [
    "DamagedSummaryError",
    "McapFilesReadBackend",
    "McapReadBackend",
    "McapStreamReadBackend",
    "McapWriteBackend",
    "SkippedChunk",
    "load_decompressors",
]

_LOG = logging.getLogger(__name__)

#: Most memory spent sorting the messages of a file read record by record whose messages are not
#: in log-time order (a file with an index is sorted through it, in constant memory).
MAX_SORTED_BYTES = 2**30
#: The MCAP record type of a chunk (its first byte).
_CHUNK_OPCODE = 0x06
#: Memory a message held for sorting costs beyond its data (a RawMessage and its bytes: ~250 B).
_HELD_OVERHEAD = 256


#: An MCAP file's last bytes: the footer record (opcode, length, summary start, summary offset
#: start, summary CRC) and the closing magic.
_FOOTER = struct.Struct("<BQQQI8s")
_FOOTER_OPCODE = 0x02
_FOOTER_LENGTH = 8 + 8 + 4  # the footer record's content: summary start, offsets start, CRC


class DamagedSummaryError(LogReadError):
    """The summary section of an MCAP file (its index, channels and counts) does not match its CRC."""


def _footer(stream: BinaryIO, size: int) -> tuple[int, int] | None:
    """``(summary_start, summary_crc)`` of the footer that ends a complete MCAP file; None when
    its last bytes are no footer and closing magic (a file cut short)."""
    if size < _FOOTER.size:
        return None
    stream.seek(size - _FOOTER.size)
    op, length, summary_start, _offsets, crc, magic = _FOOTER.unpack(stream.read(_FOOTER.size))
    if op != _FOOTER_OPCODE or length != _FOOTER_LENGTH or magic != MCAP_MAGIC:
        return None
    return summary_start, crc


def _check_summary_crc(stream: BinaryIO, size: int) -> None:
    """DamagedSummaryError when the footer's summary CRC (not 0) does not match the summary section.

    The CRC covers the summary section and the footer up to the CRC itself; the ``mcap`` package's
    reader does not check it, and a damaged index or count then read as a wrong one.
    """
    from isal.isal_zlib import crc32

    footer = _footer(stream, size)
    if footer is None:
        return  # no footer where a complete file has it (cut short?): the reader says what is wrong
    summary_start, crc = footer
    end = size - 8 - 4  # up to the CRC field, before the magic
    if crc == 0 or not 0 < summary_start <= end:
        return  # no CRC written, or no summary (the reader handles both)
    stream.seek(summary_start)
    actual, left = 0, end - summary_start
    while left > 0:
        block = stream.read(min(left, 1 << 20))
        if not block:
            return  # shorter than it says: the reader says what is wrong
        actual = crc32(block, actual)
        left -= len(block)
    if actual != crc:
        msg = (
            f"MCAP summary section (index, channels, counts) damaged: its CRC is {actual:#010x}, "
            f"the footer says {crc:#010x}"
        )
        raise DamagedSummaryError(msg)


def _chunk_records(chunk: Any) -> list[Any]:
    """The records of ``chunk`` (an ``mcap`` Chunk record), its CRC checked: the library's
    ``breakup_chunk(chunk, validate_crc=True)``, with ISA-L's CRC-32 for zstd chunks.

    The library's check takes zlib's CRC-32, 17 times slower (0.2 ms a MiB; the one-hour session
    reads 740 MiB). Raises what the library raises: its ``CRCValidationError``, zstandard's error
    on damaged data.
    """
    import zstandard
    from isal.isal_zlib import crc32
    from mcap.stream_reader import CRCValidationError, breakup_chunk

    if chunk.compression != "zstd":
        return breakup_chunk(chunk, validate_crc=True)
    data = zstandard.decompress(chunk.data, chunk.uncompressed_size)
    actual = crc32(data)
    if chunk.uncompressed_crc != 0 and actual != chunk.uncompressed_crc:
        raise CRCValidationError(expected=chunk.uncompressed_crc, actual=actual, record=chunk)
    return breakup_chunk(dataclasses.replace(chunk, compression="", data=data))


@dataclass(frozen=True)
class SkippedChunk:
    """A chunk of an indexed MCAP file or ROS 1 bag that could not be read, skipped by
    ``--salvage`` (or one message of it, :attr:`one_message`)."""

    offset: int  # byte of the file where it starts
    file_size: int  # bytes
    reason: str
    start_ns: int  # log times of its first and last message, from the index
    end_ns: int
    #: The MCAP file it is in, when that is not the log named (a ROS 2 bag folder's storage file).
    file: Path | None = None
    #: One message of the chunk skipped, not the chunk (a ROS 1 message whose time is damaged:
    #: ``reason`` says which; the chunk's other messages are read).
    one_message: bool = False


class FileRecords:
    """An MCAP file's metadata and attachment records: how many (``len``), and the records, read
    one at a time as they are iterated (an attachment may be a map or a point cloud of a gigabyte:
    all of them read at once, or held through a session, took that memory)."""

    def __init__(self, count: int, read: Callable[[], Iterator[Any]]) -> None:
        self._count = count
        self._read = read

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Iterator[Any]:
        return self._read()

    @classmethod
    def joined(cls, parts: list[FileRecords]) -> FileRecords:
        """The records of several files (a split bag's), one file's after the other's."""
        return cls(sum(map(len, parts)), lambda: itertools.chain.from_iterable(parts))


#: The name of the metadata record rosbag2 (and rosbags) writes into each MCAP file of a bag:
#: the bag's metadata.yaml as it was then. rosbag2 reads a bare MCAP file's format version (how
#: its channels spell QoS), ``custom_data``, ROS distribution and message compression from it
#: (its counts and files from the summary): an MCAP output keeps one, the first file's of a
#: split bag (the files' records say the same of those).
ROSBAG2_METADATA = "rosbag2"


def _not_bookkeeping(records: Iterable[Any], *, keep: bool) -> Iterator[Any]:
    """``records``, without rosbag2's metadata record (:data:`ROSBAG2_METADATA`) unless ``keep``."""
    from mcap.records import Metadata

    if keep:
        return iter(records)
    return (r for r in records if not (isinstance(r, Metadata) and r.name == ROSBAG2_METADATA))


def _indexed_records(reader: Any, path: Path, *, bookkeeping: bool = True) -> FileRecords:
    """The metadata and attachment records of the MCAP file ``path`` (``reader``: an ``mcap``
    SeekingReader of it whose file stays open while they are read), rosbag2's bookkeeping record
    only with ``bookkeeping``: through its summary's indexes, else by a pass over its records
    (:func:`_records_by_pass`). The indexes are optional: a file written without them (a
    summary of statistics alone, or no summary) had its records left out without a word."""
    summary = reader.get_summary()
    if _unindexed_records(summary):
        return FileRecords(
            sum(1 for _ in _records_by_pass(path, bookkeeping=bookkeeping)),
            lambda: _records_by_pass(path, bookkeeping=bookkeeping),
        )
    metadata = sum(
        bookkeeping or index.name != ROSBAG2_METADATA for index in summary.metadata_indexes
    )
    return FileRecords(
        metadata + len(summary.attachment_indexes),
        lambda: itertools.chain(
            _not_bookkeeping(reader.iter_metadata(), keep=bookkeeping), reader.iter_attachments()
        ),
    )


def _unindexed_records(summary: Any) -> bool:
    """Whether an MCAP file of the ``summary`` (None: none) may hold metadata or attachment
    records its summary does not index: its statistics count more than it indexes, or it
    indexes none and has no statistics to say there are none."""
    if summary is None:
        return True
    indexed = len(summary.metadata_indexes) + len(summary.attachment_indexes)
    stats = summary.statistics
    if stats is None:
        return indexed == 0
    return int(stats.metadata_count) + int(stats.attachment_count) > indexed


def _records_by_pass(path: Path, *, bookkeeping: bool) -> Iterator[Any]:
    """The metadata and attachment records of the MCAP file ``path`` (rosbag2's only with
    ``bookkeeping``), found by a pass over its records (its chunks, which hold none, left
    compressed), one at a time."""
    from mcap.records import Attachment, Metadata
    from mcap.stream_reader import StreamReader

    size = path.stat().st_size
    with path.open("rb") as stream:
        records = StreamReader(stream, emit_chunks=True, record_size_limit=max(size, 1)).records
        found = (r for r in records if isinstance(r, Attachment | Metadata))
        yield from _not_bookkeeping(found, keep=bookkeeping)


def storage_file_records(path: Path, *, bookkeeping: bool) -> FileRecords:
    """The metadata and attachment records of the MCAP storage file ``path`` of a ROS 2 bag
    folder (which rosbags reads: no reader of ours holds it open), rosbag2's bookkeeping record
    only with ``bookkeeping`` (:func:`_indexed_records`); the file is opened again to read
    them, one at a time."""
    from mcap.reader import SeekingReader

    size = path.stat().st_size
    with path.open("rb") as stream:
        reader = SeekingReader(stream, record_size_limit=max(size, 1))
        count = len(_indexed_records(reader, path, bookkeeping=bookkeeping))

    def read() -> Iterator[Any]:
        with path.open("rb") as stream:
            reader = SeekingReader(stream, record_size_limit=max(size, 1))
            yield from _indexed_records(reader, path, bookkeeping=bookkeeping)

    return FileRecords(count, read)


class McapReadBackend:
    """Bare MCAP files (ros1 or ros2 profile) through the ``mcap`` package."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.stream: BinaryIO | None = None
        self.reader: Any = None
        self.channels: tuple[Channel, ...] = ()
        self._by_id: dict[int, Channel] = {}
        self.start_ns = 0
        self.end_ns = 0
        self.profile = ""
        self.qos_style: QosStyle | None = None
        #: ``--salvage``: a chunk that cannot be read (CRC, compression, framing) is skipped and
        #: said in :attr:`skipped_chunks`, and the chunks after it are read (else it is an error).
        self.skip_damaged_chunks = False
        self.skipped_chunks: list[SkippedChunk] = []

    def open(self) -> None:
        load_decompressors()
        from mcap.reader import SeekingReader

        self.stream = self.path.open("rb")
        size = self._size = self.path.stat().st_size
        # Chunk CRCs are checked on every chunk read; no record can be longer than the file, so a
        # corrupt length never makes the reader allocate more than the file's size.
        self.reader = SeekingReader(self.stream, validate_crcs=True, record_size_limit=max(size, 1))
        self.profile = self.reader.get_header().profile
        _check_summary_crc(self.stream, size)
        summary = self.reader.get_summary()
        if summary is None:
            msg = (
                f"{self.path}: MCAP file without summary (truncated or still being recorded?); "
                "--salvage keeps the messages before the end, or try `mcap recover`"
            )
            raise LogReadError(msg)
        counts = summary.statistics.channel_message_counts if summary.statistics else None
        if counts is None:  # no statistics record: count what the file holds
            counts = self._count_messages()
        self.channels, self._by_id, self.qos_style = _channels(
            summary.channels, summary.schemas, counts
        )
        if summary.statistics and summary.statistics.message_count:
            self.start_ns = int(summary.statistics.message_start_time)
            self.end_ns = int(summary.statistics.message_end_time)
        elif self._times:
            self.start_ns, self.end_ns = self._times

    _times: tuple[int, int] | None = None
    _size = 0  # bytes of the file, when opened

    def _count_messages(self) -> dict[int, int]:
        """Messages per channel id and the time range, by reading every message (no statistics)."""
        counts: dict[int, int] = {}
        first, last = None, None
        for _schema, ch, msg in self.reader.iter_messages(log_time_order=False):
            counts[ch.id] = counts.get(ch.id, 0) + 1
            first = msg.log_time if first is None else min(first, msg.log_time)
            last = msg.log_time if last is None else max(last, msg.log_time)
        if first is not None and last is not None:
            self._times = (int(first), int(last))
        return counts

    def file_records(self, *, bookkeeping: bool = True) -> FileRecords:
        """The file's metadata and attachment records (``mcap.records.Metadata`` and
        ``Attachment``), through its summary's indexes (rosbag2's bookkeeping record,
        :data:`ROSBAG2_METADATA`, only with ``bookkeeping``): they belong to no channel, and an
        MCAP output copies them."""
        assert self.reader is not None
        return _indexed_records(self.reader, self.path, bookkeeping=bookkeeping)

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        if self.skip_damaged_chunks:
            yield from self._around_damaged_chunks(topics)
            return
        wanted = self._wanted(topics)
        chunks = self._chunks_in_sequence(wanted)
        if chunks is not None:
            yield from self._chunk_by_chunk(chunks, wanted)
            return
        if not self.reader.get_summary().chunk_indexes and (
            record_by_record := self._record_by_record()
        ):
            try:
                yield from record_by_record.messages(topics)
            finally:
                record_by_record.close()
            return
        by_id = self._by_id
        for _schema, ch, msg in self.reader.iter_messages(topics=topics, log_time_order=True):
            yield RawMessage(by_id[ch.id], msg.log_time, msg.data, msg.publish_time, msg.sequence)

    def _record_by_record(self) -> McapStreamReadBackend | None:
        """This file read record by record (:class:`McapStreamReadBackend`, our channels), when
        its summary indexes no chunk: written without chunks (rosbag2's ``fastwrite`` preset) or
        without a chunk index. Its messages stream in file order when that is log-time order, as
        recorders write them, and are sorted in memory up to :data:`MAX_SORTED_BYTES` when not.
        The library's reader sorted every message of such a file in memory before the first (a
        560 MB file took 720 MB). None when a record does not read (the library's reader says
        what is wrong, as before) or when the messages are out of order and too many to sort
        (the library's reader sorts them, as before: the file is valid, its summary whole)."""
        stream = McapStreamReadBackend(self.path)
        try:
            stream.open()
        except Exception as err:
            stream.close()
            reraise_unless_damage(err)
            return None
        if not stream.complete or not stream.sorted_by_time:
            stream.close()
            return None
        # The summary's channels, the ones this reader announced, not the data section's copies.
        stream._by_id = {cid: ch for cid, ch in self._by_id.items() if cid in stream._by_id}
        # A valid file, out of order: sorted without a warning, as the library's reader did (the
        # warning is a file without a summary's, whose order nothing else vouches for).
        stream._order_said = True
        return stream

    def _wanted(self, topics: set[str] | None) -> set[int]:
        """MCAP channel ids of ``topics`` (every channel we know when None)."""
        channels = self.reader.get_summary().channels
        return {
            cid
            for cid, ch in channels.items()
            if cid in self._by_id and (topics is None or ch.topic in topics)
        }

    def _chunks_with(self, wanted: set[int]) -> list[Any]:
        """Chunk indexes that may hold messages of the channels ``wanted`` (any, without a list
        of the chunk's channels)."""
        return [
            index
            for index in self.reader.get_summary().chunk_indexes
            if wanted & set(index.message_index_offsets) or not index.message_index_offsets
        ]

    def _chunks_in_sequence(self, wanted: set[int]) -> list[Any] | None:
        """The chunk indexes holding the channels ``wanted``, in file order, when each chunk's messages all come
        before the next one's in the library's log-time order (log time, then chunk, then place in
        the chunk), as recorders write them; None when chunks overlap in time (or there is no
        index), for the library's merge.

        The library merges through a heap of every message of every open chunk, in Python: about a
        third of the session's reading time. Chunks that follow each other in time need no merge,
        only each chunk's messages sorted by log time (stable: the place in the chunk breaks ties).
        """
        summary = self.reader.get_summary()
        if not summary.chunk_indexes:
            return None
        chunks = sorted(
            self._chunks_with(wanted),
            key=lambda index: (index.message_start_time, index.chunk_start_offset),
        )
        for before, after in itertools.pairwise(chunks):
            if before.message_end_time > after.message_start_time or (
                before.message_end_time == after.message_start_time
                and before.chunk_start_offset >= after.chunk_start_offset
            ):
                return None
        return chunks

    def _chunk_by_chunk(self, chunks: list[Any], wanted: set[int]) -> Iterator[RawMessage]:
        """The messages of ``chunks`` (:meth:`_chunks_in_sequence`), each chunk's sorted by log time.

        Only while each chunk's messages lie within the times its index gives: a chunk whose
        index does not bound them (a writer's bug, such as a start time that leaves out messages
        logged at time 0) hands over to the library's merge from that chunk on, which up to there
        gave the same messages."""
        by_id = self._by_id
        ahead = self._read_ahead(chunks, wanted)
        try:
            for k, (index, messages) in enumerate(zip(chunks, ahead, strict=True)):
                times = [m.log_time for m in messages]
                if times and not (
                    index.message_start_time <= min(times) and max(times) <= index.message_end_time
                ):
                    ahead.close()  # (the merge reads the chunks after this one itself)
                    offset = index.chunk_start_offset
                    yield from self._merge(
                        [(m.log_time, offset, at, m) for at, m in enumerate(messages)]
                        + [
                            (c.message_start_time, c.chunk_start_offset, -1, c)
                            for c in chunks[k + 1 :]
                        ],
                        wanted,
                        skip_damaged=False,
                    )
                    return
                if any(a > b for a, b in itertools.pairwise(times)):
                    messages.sort(key=lambda m: m.log_time)
                for m in messages:
                    yield RawMessage(
                        by_id[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence
                    )
        finally:
            ahead.close()  # its thread ends with the reading, however it ends

    def _read_ahead(self, chunks: list[Any], wanted: set[int]) -> Generator[list[Any]]:
        """:meth:`_messages_of` each of ``chunks`` in turn (strict), the next one read meanwhile by a
        thread of its own: reading the file, decompressing and checking a chunk (native, outside
        the interpreter's lock; the records' split is Python) overlap with the caller's work on the
        one before. A chunk's error is raised when its turn comes, as read in turn. Without
        ``os.pread`` (Windows), or where no thread can start, in turn.

        The thread starts only when the second chunk is asked for (it reads the third while the
        caller's thread reads the second): a split bag's files merged by log time are each asked
        for their first message at once, and a thread and a chunk read ahead for each of a hundred
        files that follow each other in time were a hundred of each before the first message."""
        read = functools.partial(self._messages_of, wanted=wanted, strict=True)
        threaded = hasattr(os, "pread")
        pool = threads_in_this_context(1, "rose-mcap-reader")  # (its thread starts on a submit)
        try:
            ahead: Future[list[Any]] | None = None  # the chunk read ahead, if one is
            for k, index in enumerate(chunks):
                coming = None
                if threaded and 0 < k < len(chunks) - 1:
                    with contextlib.suppress(RuntimeError):  # "can't start new thread": in turn
                        coming = pool.submit(read, chunks[k + 1])
                current = ahead.result() if ahead is not None else read(index)
                ahead = coming
                yield current
        finally:
            pool.shutdown(wait=True, cancel_futures=True)

    def _messages_of(self, index: Any, wanted: set[int], *, strict: bool) -> list[Any]:
        """The messages of the channels ``wanted`` in the chunk ``index`` points to, in file
        order; ``strict``: a message on a channel the file does not define is an error (as in
        the library's reader, which looks it up), else left out."""
        messages = []
        for m in self._read_chunk(index):
            if m.channel_id in wanted:
                messages.append(m)
            elif strict and m.channel_id not in self._by_id:
                msg = f"message on channel id {m.channel_id}, which the file does not define"
                raise ValueError(msg)
        return messages

    def _merge(
        self, items: list[tuple[int, int, int, Any]], wanted: set[int], *, skip_damaged: bool
    ) -> Iterator[RawMessage]:
        """The ``mcap`` reader's own merge, in the same order (log time, then file position).

        ``items``: ``(log time, chunk offset, place in the chunk, message)`` for messages read,
        ``(start time, chunk offset, -1, chunk index)`` for chunks to read when their time comes.
        ``skip_damaged``: a chunk that cannot be read is said in :attr:`skipped_chunks` and
        skipped (else its error is raised).
        """
        # A tie-breaker keeps the items themselves out of every comparison.
        tie = itertools.count()
        queue = [(t, offset, at, next(tie), item) for t, offset, at, item in items]
        heapq.heapify(queue)
        while queue:
            _, offset, position, _, item = heapq.heappop(queue)
            if position >= 0:
                ch = self._by_id[item.channel_id]
                yield RawMessage(ch, item.log_time, item.data, item.publish_time, item.sequence)
                continue
            try:
                messages = self._messages_of(item, wanted, strict=not skip_damaged)
            except Exception as err:  # any library error: this chunk is damaged
                reraise_unless_damage(err)
                if not skip_damaged:
                    raise
                reason = short(str(err) or type(err).__name__, 120)
                self.skipped_chunks.append(
                    SkippedChunk(
                        offset, self._size, reason, item.message_start_time, item.message_end_time
                    )
                )
                continue
            for at, m in enumerate(messages):
                heapq.heappush(queue, (m.log_time, offset, at, next(tie), m))

    def _read_chunk(self, index: Any) -> list[Any]:
        """The message records of the chunk ``index`` points to, in file order (CRC checked).

        The record as the index bounds it: a damaged length inside it reads no further than the
        record (a length of 2**60 would have been read from the file)."""
        from mcap.data_stream import ReadDataStream
        from mcap.records import Chunk, Message

        assert self.stream is not None
        offset = index.chunk_start_offset
        raw = read_at(self.stream, min(index.chunk_length, self._size - offset), offset)
        if len(raw) < 9 or raw[0] != _CHUNK_OPCODE:
            msg = "no chunk record where the index points"
            raise ValueError(msg)
        chunk = Chunk.read(ReadDataStream(io.BytesIO(raw[9:])))
        return [r for r in _chunk_records(chunk) if isinstance(r, Message)]

    def _around_damaged_chunks(self, topics: set[str] | None) -> Iterator[RawMessage]:
        """:meth:`messages` through the chunk index, skipping the chunks that cannot be read.

        The ``mcap`` reader's own merge, in the same order (log time, then file position), with each
        chunk read on its own: a flipped bit in one chunk of an hour's recording loses that chunk's
        seconds, not the rest of the hour."""
        summary = self.reader.get_summary()
        if not summary.chunk_indexes:
            # No chunks (or no chunk index): the library reads it record by record, in file order;
            # its log-time order would read (and sort) the whole file before the first message,
            # so a damaged record would leave nothing to keep.
            by_id = self._by_id
            for _schema, ch, msg in self.reader.iter_messages(topics=topics, log_time_order=False):
                yield RawMessage(
                    by_id[ch.id], msg.log_time, msg.data, msg.publish_time, msg.sequence
                )
            return
        wanted = self._wanted(topics)
        yield from self._merge(
            [
                (index.message_start_time, index.chunk_start_offset, -1, index)
                for index in self._chunks_with(wanted)
            ],
            wanted,
            skip_damaged=True,
        )

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None
        self.reader = None


def _channels(
    mcap_channels: dict[int, Any], schemas: dict[int, Any], counts: dict[int, int]
) -> tuple[tuple[Channel, ...], dict[int, Channel], QosStyle | None]:
    """Our channels (ids 0..n-1 in MCAP channel id order) from MCAP channel and schema records, the
    map from MCAP channel id, and the QoS style of the first CDR channel (None without one)."""
    channels: list[Channel] = []
    by_id: dict[int, Channel] = {}
    style: QosStyle | None = None
    for channel_id in sorted(mcap_channels):
        ch = mcap_channels[channel_id]
        schema = schemas.get(ch.schema_id)
        name = schema.name if schema is not None else ""
        encoding = schema.encoding if schema is not None else ""
        data = bytes(schema.data) if schema is not None else b""
        channel = Channel(
            id=len(channels),
            topic=ch.topic,
            msgtype=normalize_msgtype(name) if ch.message_encoding in {"ros1", "cdr"} else name,
            message_encoding=ch.message_encoding,
            msgdef=data.decode("utf-8", errors="replace"),
            msgdef_encoding=encoding,
            digest=ch.metadata.get("md5sum", "") or ch.metadata.get("type_hash", ""),
            message_count=int(counts.get(channel_id, 0)),
            callerid=ch.metadata.get("callerid"),
            latching=parse_latching(ch.metadata.get("latching")),
            metadata=dict(ch.metadata),
            schema_name=name,
            schema_data=data,
        )
        channels.append(channel)
        by_id[channel_id] = channel
        if style is None and ch.message_encoding == "cdr":
            style = qos_style(ch.metadata.get("offered_qos_profiles", ""))
    return tuple(channels), by_id, style


class McapStreamReadBackend(McapReadBackend):
    """What can be read of a bare MCAP file from its start, when its end (the summary) is missing or
    damaged: a recording cut off by a crash or a full disk (``--salvage``).

    Also the reader of a complete file written without a summary (the MCAP specification makes it
    optional), with or without its closing magic bytes: then :attr:`complete` is True and nothing
    is lost.

    The file is read record by record (complete chunks only) up to the first record that cannot be
    read; :attr:`damage` says where and why. The file is read twice: :meth:`open` for the channels and
    their counts (which the output needs before the first message), :meth:`messages` for the messages,
    so memory stays that of one chunk. Recorders write messages as they arrive, in log-time order;
    when they are not, :meth:`messages` sorts them in memory (up to :data:`MAX_SORTED_BYTES`); beyond
    that a complete file is refused (``mcap recover`` gives it an index) and a damaged one is
    salvaged in file order.
    """

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.damage = ""
        #: As :attr:`Ros1StreamReadBackend.complete`: the file ends with its footer, no summary.
        self.complete = False
        self._end: int | None = None  # records open() read: messages() reads as many
        self._in_order = True  # messages in log-time order in the file
        self._held_bytes = 0  # memory the messages would take to sort them
        self._order_said = False
        self._damage_at = -1  # where the first record that cannot be read starts
        self._metadata: list[Any] = []  # metadata records of the data section
        self._attachments_at: list[int] = []  # where its attachment records start (not held)
        self._record_at = -1  # where the record _records handed out last starts

    def _records(self) -> Iterator[Any]:
        """Records from the start of the file up to the first unreadable one (which sets
        :attr:`damage`), or as many as :meth:`open` read (a recording still being written has
        more by the second pass, which must hand out what the first one counted; counted in
        records, since a chunk's records all come at the file position after the chunk)."""
        load_decompressors()
        from mcap.stream_reader import StreamReader

        assert self.stream is not None
        self.stream.seek(0)
        size = self.path.stat().st_size
        reader = StreamReader(self.stream, validate_crcs=True, record_size_limit=max(size, 1))
        records = reader.records
        read = 0
        while self._end is None or read < self._end:
            offset = self.stream.tell()
            try:
                record = next(records)
            except StopIteration:
                break
            except Exception as err:  # the damaged end: any library error, stop there
                reraise_unless_damage(err)
                reason = str(err) or type(err).__name__
                self.damage = f"unreadable from byte {offset} of {size}: {short(reason, 120)}"
                self._damage_at = offset
                break
            read += 1
            self._record_at = offset
            yield record
        if self._end is None:
            self._end = read

    def open(self) -> None:
        from mcap.records import Attachment, DataEnd, Footer, Header, Message, Metadata, Schema
        from mcap.records import Channel as McapChannel

        self.stream = self.path.open("rb")
        schemas: dict[int, Any] = {}
        mcap_channels: dict[int, Any] = {}
        counts: dict[int, int] = {}
        first = last = None
        footer = data_end = False
        for record in self._records():
            if isinstance(record, DataEnd):
                # What follows is the summary, which this reader does not trust (missing or
                # damaged): its copies of the definitions are not read over the data section's.
                data_end = True
            elif data_end:
                footer |= isinstance(record, Footer)
            elif isinstance(record, Header):
                self.profile = record.profile
            elif isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, McapChannel):
                mcap_channels[record.id] = record
            elif isinstance(record, Message):
                counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                self._in_order &= last is None or record.log_time >= last
                self._held_bytes += len(record.data) + _HELD_OVERHEAD
                first = record.log_time if first is None else min(first, record.log_time)
                last = record.log_time if last is None else max(last, record.log_time)
            elif isinstance(record, Metadata):
                self._metadata.append(record)
            elif isinstance(record, Attachment):
                # Read again when copied: an attachment (a map, a point cloud) may be large.
                self._attachments_at.append(self._record_at)
            elif isinstance(record, Footer):
                footer = True
        if footer and self.damage:  # e.g. the closing magic bytes missing: every record read
            _LOG.warning("%s: %s, after its footer: nothing lost", self.path, self.damage)
            self.damage = ""
        elif (
            data_end and self.damage and _footer(self.stream, self.path.stat().st_size) is not None
        ):
            # A summary that does not read, between the data's end and an intact footer.
            _LOG.warning("%s: %s, in its summary: nothing lost", self.path, self.damage)
            self.damage, footer = "", True
        elif data_end and self.damage and self._damaged_footer():
            # The footer itself damaged (its length, its op), the data section whole before it.
            _LOG.warning(
                "%s: the footer is damaged (%s); read record by record, nothing lost",
                self.path,
                self.damage,
            )
            self.damage, footer = "", True
        self.complete = footer
        if not self.damage:
            self.damage = "the file ends without a summary" if footer else "no summary at the end"
        self.channels, self._by_id, self.qos_style = _channels(mcap_channels, schemas, counts)
        if first is not None and last is not None:
            self.start_ns, self.end_ns = int(first), int(last)

    def file_records(self, *, bookkeeping: bool = True) -> FileRecords:
        """The metadata and attachment records :meth:`open` read (those before any damage;
        rosbag2's bookkeeping record only with ``bookkeeping``); the attachments read again, one
        at a time."""
        metadata = list(_not_bookkeeping(self._metadata, keep=bookkeeping))
        return FileRecords(
            len(metadata) + len(self._attachments_at),
            lambda: self._metadata_and_attachments(metadata),
        )

    def _metadata_and_attachments(self, metadata: list[Any]) -> Iterator[Any]:
        from mcap.stream_reader import StreamReader

        yield from metadata
        assert self.stream is not None
        for offset in self._attachments_at:
            self.stream.seek(offset)
            size = self.path.stat().st_size
            reader = StreamReader(self.stream, skip_magic=True, record_size_limit=max(size, 1))
            yield next(reader.records)

    def _damaged_footer(self) -> bool:
        """Whether the first record that cannot be read is where the footer belongs, before the
        closing magic bytes, which are there: the file is complete, its footer damaged (a file
        cut short ends elsewhere than in magic bytes)."""
        assert self.stream is not None
        size = self.path.stat().st_size
        if self._damage_at < size - _FOOTER.size:
            return False
        self.stream.seek(size - len(MCAP_MAGIC))
        return self.stream.read(len(MCAP_MAGIC)) == MCAP_MAGIC

    @property
    def sorted_by_time(self) -> bool:
        """Whether :meth:`messages` gives log-time order (else file order: damaged and too large)."""
        return self._in_order or self._held_bytes <= MAX_SORTED_BYTES

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        if not self._in_order:
            if not self.sorted_by_time and self.complete:
                msg = (
                    f"{self.path}: messages not in log-time order and no index to sort them by "
                    f"({self._held_bytes / 2**20:.0f} MiB to sort in memory, more than "
                    f"{MAX_SORTED_BYTES // 2**20} MiB); `mcap recover` writes a copy with an index"
                )
                raise LogReadError(msg)
            if not self._order_said:
                self._order_said = True
                how = "sorted in memory" if self.sorted_by_time else "too large to sort, file order"
                _LOG.warning("%s: messages not in log-time order, no index: %s", self.path, how)
        if self._in_order or not self.sorted_by_time:
            yield from self._file_order(topics)
        else:  # a stable sort: messages of equal log time keep their file order
            yield from sorted(self._file_order(topics), key=lambda m: m.log_time_ns)

    def _file_order(self, topics: set[str] | None) -> Iterator[RawMessage]:
        from mcap.records import DataEnd, Message

        by_id = self._by_id
        for record in self._records():
            if isinstance(record, DataEnd):
                return  # as open() counted: no message after the data section
            if isinstance(record, Message) and record.channel_id in by_id:
                channel = by_id[record.channel_id]
                if topics is None or channel.topic in topics:
                    yield RawMessage(
                        channel, record.log_time, record.data, record.publish_time, record.sequence
                    )


class McapFilesReadBackend:
    """The MCAP files of a ROS 2 bag folder split over several (rosbag2's ``--max-bag-size``,
    ``--max-bag-duration``) that rosbags cannot open because one of them is damaged (cut short,
    its summary damaged or missing): each file read as it would be read on its own (``parts``,
    opened: through its index, or record by record; see
    :meth:`rose_logs.reader.LogReader._damaged_mcap_storage`), their messages merged by log time
    (:func:`~rose_logs.storage.records.merged_by_log_time`).

    The same channel in several files (topic, type, encoding, definition and metadata alike)
    is one channel, its counts summed; the time range spans the files'. A file read through its
    index counts what its index declares, one read record by record what was read
    (:attr:`counts_declared`). With :attr:`skip_damaged_chunks` (``--salvage``) each indexed
    file skips the chunks that cannot be read, said in :attr:`skipped_chunks` with the file they
    are in, and a file whose reading fails part way is said in :attr:`damaged_files`, the other
    files read on.
    """

    def __init__(self, parts: list[McapReadBackend]) -> None:
        self.path = parts[0].path.parent
        self.parts = parts
        self.skip_damaged_chunks = False
        self.skipped_chunks: list[SkippedChunk] = []
        #: Whether a file's counts and time range are its index's (a file read through it),
        #: not what was read: a chunk it skips is in the counts (the reader's
        #: :attr:`~rose_logs.reader.LogReader.counts_declared`).
        self.counts_declared = any(not isinstance(p, McapStreamReadBackend) for p in parts)
        self.profile = parts[0].profile
        self.qos_style: QosStyle | None = next(
            (part.qos_style for part in parts if part.qos_style is not None), None
        )
        firsts: dict[tuple[Any, ...], Channel] = {}
        counts: dict[tuple[Any, ...], int] = {}
        keys: list[dict[int, tuple[Any, ...]]] = []
        for part in parts:
            keys.append({})
            for channel in part.channels:
                key = (
                    channel.topic,
                    channel.msgtype,
                    channel.message_encoding,
                    channel.schema_name,
                    channel.msgdef_encoding,
                    channel.msgdef,
                    channel.schema_data,
                    tuple(sorted(channel.metadata.items())),
                )
                firsts.setdefault(key, channel)
                counts[key] = counts.get(key, 0) + channel.message_count
                keys[-1][channel.id] = key
        ours = {
            key: dataclasses.replace(channel, id=n, message_count=counts[key])
            for n, (key, channel) in enumerate(firsts.items())
        }
        self.channels: tuple[Channel, ...] = tuple(ours.values())
        #: Per part, our channel of each of the part's channel ids.
        self._ours = [{cid: ours[key] for cid, key in part.items()} for part in keys]
        ranges = [
            (part.start_ns, part.end_ns)
            for part in parts
            if any(channel.message_count for channel in part.channels)
        ]
        self.start_ns = min((start for start, _ in ranges), default=0)
        self.end_ns = max((end for _, end in ranges), default=0)
        #: The file whose reading failed, if one did: the error is about it, not the folder.
        self.failed_file: Path | None = None
        #: ``--salvage``: each file that could not be read to its end, in words (as
        #: :attr:`~rose_logs.storage.rosbags.RosbagsReadBackend.damaged_files`).
        self.damaged_files: list[str] = []

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        yield from merged_by_log_time(
            self._part_messages(part, ours, topics)
            for part, ours in zip(self.parts, self._ours, strict=True)
        )

    def _part_messages(
        self, part: McapReadBackend, ours: dict[int, Channel], topics: set[str] | None
    ) -> Iterator[RawMessage]:
        """The messages of the file ``part`` as our channels (``ours``: of each of its channel
        ids), its skipped chunks said in :attr:`skipped_chunks`. A failure part way (damage the
        chunk reader does not skip: a file without chunks, a damaged record after its data) is
        raised naming the file, or with ``--salvage`` said in :attr:`damaged_files`: raised, it
        ended the merge, and the other files' later messages were lost with it."""
        part.skip_damaged_chunks = self.skip_damaged_chunks
        read = 0
        try:
            for m in part.messages(topics):
                read += 1
                yield RawMessage(
                    ours[m.channel.id], m.log_time_ns, m.data, m.publish_time_ns, m.sequence
                )
        except Exception as err:
            reraise_unless_damage(err)
            if not self.skip_damaged_chunks or len(self.parts) < 2:
                self.failed_file = part.path
                raise
            why = str(err).removeprefix(f"{part.path}: ") or type(err).__name__
            self.damaged_files.append(read_part_way(part.path, read, why))
        finally:
            self.skipped_chunks.extend(
                dataclasses.replace(chunk, file=part.path) for chunk in part.skipped_chunks
            )
            part.skipped_chunks.clear()

    def file_records(self) -> FileRecords:
        """The metadata and attachment records of the files, one file's after the other's
        (:meth:`McapReadBackend.file_records`), rosbag2's bookkeeping record the first file's."""
        return FileRecords.joined(
            [part.file_records(bookkeeping=i == 0) for i, part in enumerate(self.parts)]
        )

    def close(self) -> None:
        for part in self.parts:
            part.close()


def load_decompressors() -> None:
    """Load zstd and lz4 before ``mcap``'s reader loads them, as any import: it loads each in a
    ``try`` and reads without one that failed (a native library that could not be mapped under
    ``ulimit -v``), and every chunk compressed with it was "unsupported compression": a sound log
    said corrupt, its chunks skipped by ``--salvage``. Failing here, it is the ImportError it is
    ("out of memory (library zstandard could not be loaded)")."""
    import isal.isal_zlib  # noqa: F401  (our CRC-32 of the chunks)
    import lz4.frame  # type: ignore[import-untyped]  # noqa: F401
    import zstandard  # noqa: F401


class McapWriteBackend(WriteBackend):
    """Bare MCAP output, ``ros1`` or ``ros2`` profile.

    Every ``cdr`` channel gets the ``offered_qos_profiles`` metadata the ``ros2`` profile requires: the
    input's text when copied from an MCAP file that has it, else the channel's profiles (a default
    publisher's when it has none), spelled in ``qos_style``.
    """

    def __init__(self, path: Path, serialization: str, qos_style: QosStyle = "v9") -> None:
        self.path = path
        self.serialization = serialization
        self.qos_style = qos_style
        self.stream: BinaryIO | None = None
        self.writer: Any = None
        self.schemas: dict[tuple[str, str, bytes], int] = {}
        self.channels: list[int] = []
        # QoS profiles -> their YAML text: a YAML dump a channel took most of the time to add
        # a channel (most channels of a log share one or two profiles).
        self.qos_texts: dict[tuple[Any, ...], str] = {}
        self.definitions = KnownDefinitions()

    def open(self) -> None:
        from rose_logs.storage.mcap_writer import ThreadedMcapWriter

        self.stream = self.path.open("wb")
        self.writer = ThreadedMcapWriter(self.stream)
        self.writer.start(
            profile="ros1" if self.serialization == "ros1" else "ros2", library="rose-bag"
        )

    def add(self, channel: Channel) -> int:
        ros1 = channel.message_encoding == "ros1"
        if channel.schema_name or channel.message_encoding not in {"ros1", "cdr"}:
            name, encoding = channel.schema_name, channel.msgdef_encoding
            # The bytes as stored: a binary schema (protobuf's) read as text lost its bytes that
            # are no UTF-8, and its channel could no longer be decoded.
            data = channel.schema_data or channel.msgdef.encode("utf-8")
        else:
            text, _digest = self.definitions(channel, 1 if ros1 else 2)
            name = ros1_msgtype(channel.msgtype) if ros1 else channel.msgtype
            encoding = "ros1msg" if ros1 else (channel.msgdef_encoding or "ros2msg")
            if not text:  # no definition known (see definitions): a schema without encoding
                encoding = ""
                warn_no_definition(channel)
            data = text.encode("utf-8")
        key = (name, encoding, data)
        schema_id = self.schemas.get(key)
        if not any(key):  # a channel without schema (schema id 0, e.g. self-describing JSON)
            schema_id = 0
        elif schema_id is None:
            schema_id = self.writer.register_schema(name, encoding, data)
            self.schemas[key] = schema_id
        metadata = dict(channel.metadata)
        if not metadata and ros1:
            if channel.callerid is not None:
                metadata["callerid"] = channel.callerid
            if channel.latching is not None:
                metadata["latching"] = str(int(channel.latching))
            if channel.digest:
                metadata["md5sum"] = channel.digest
        elif channel.message_encoding == "cdr" and "offered_qos_profiles" not in metadata:
            profiles = tuple(offered_qos(channel) or [default_qos()])
            if profiles not in self.qos_texts:
                self.qos_texts[profiles] = qos_yaml(profiles, style=self.qos_style)
            metadata["offered_qos_profiles"] = self.qos_texts[profiles]
        channel_id = self.writer.register_channel(
            channel.topic, channel.message_encoding, schema_id, metadata
        )
        self.channels.append(channel_id)
        return len(self.channels) - 1

    def add_file_records(self, records: Iterable[Any]) -> None:
        """Copy an input MCAP file's metadata and attachment records (:meth:`McapReadBackend.file_records`)."""
        from mcap.records import Attachment, Metadata

        for record in records:  # (read one at a time: errors of the reading are not ours)
            try:
                if isinstance(record, Metadata):
                    self.writer.add_metadata(record.name, dict(record.metadata))
                elif isinstance(record, Attachment):
                    self.writer.add_attachment(
                        record.create_time,
                        record.log_time,
                        record.name,
                        record.media_type,
                        record.data,
                    )
            except Exception as err:
                raise as_memory_error(err) from err

    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None:
        # A chunk is compressed as it fills. A try, not a context manager: once per message.
        try:
            self.writer.add_message(self.channels[handle], log_time_ns, data, publish_ns, seq)
        except Exception as err:
            raise as_memory_error(err) from err

    def close(self) -> None:
        try:
            self.writer.finish()  # the last chunks
        except Exception as err:
            # The file is dropped by the caller: closed here, or, deleted, it held its disk space
            # as long as the error lived (the writer's thread makes a full disk show here often).
            stream, self.stream = self.stream, None
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()
            raise as_memory_error(err) from err
        if self.stream is not None:
            self.stream.close()
            self.stream = None

    def abort(self) -> None:
        stream, self.stream, writer, self.writer = self.stream, None, self.writer, None
        try:
            if writer is not None:
                writer.abort()
        finally:
            if stream is not None:
                stream.close()
