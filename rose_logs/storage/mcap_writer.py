"""An MCAP writer for long sessions: the ``mcap`` library's file, byte for byte, written from a thread.

``mcap.writer.Writer`` builds each message record in about a dozen Python calls and compresses,
checksums and writes each full chunk (1 MiB, zstd) in the caller's thread. In ``rose-bag
process`` that caller is the session's main thread, which also reads the log and hands the maps
to the analyses: the chunks' zstd and CRC took about a third of its time. Here a message record is
one ``struct.pack``, and each full chunk is compressed, checksummed and written by one thread of
its own, in order, while the caller reads on: a log whose copying outweighs its maps (camera
images) is processed 20-25 % faster (docs/measurements.md, fifty-eighth session). The file is the
library's (the same records in the same order, compressed by the same call; the same CRC-32,
by ISA-L's faster code):
``tests/logs/test_mcap_writer.py`` compares the two.
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from typing import BinaryIO

import zstandard
from isal.isal_zlib import crc32
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from rose.threads import threads_in_this_context
from rose_logs.formats import MCAP_MAGIC

__all__ = ["ThreadedMcapWriter"]

#: A message record's opcode, length, channel id, sequence, log time and publish time.
_MESSAGE_HEADER = struct.Struct("<BQHIQQ")
_MESSAGE_FIELDS_BYTES = 2 + 4 + 8 + 8
#: The footer's opcode, length, summary start and summary offsets' start: what its CRC covers.
_FOOTER_START = struct.Struct("<BQQQ")
#: Full chunks handed to the writing thread and not yet written beyond the one being written:
#: the caller waits for more. Two keep the thread busy while bounding what they hold (a chunk is
#: a little over ``chunk_size``, or one message larger than that).
_QUEUED_CHUNKS = 2


class ThreadedMcapWriter:
    """``mcap.writer.Writer`` with its defaults (zstd chunks of ``chunk_size`` bytes, every index,
    statistics, summary offsets and CRCs, no data-section CRC), the same calls and the same bytes.

    Chunks reach ``stream`` from a thread of their own, in the order of the calls; an error there
    (a full disk) is raised by a later call that hands over a chunk, by :meth:`add_metadata`,
    :meth:`add_attachment` or :meth:`finish`. Where no thread can start (a thread limit, no
    memory for its stack), they are written by the caller. The records between chunks (metadata,
    attachments) and the summary are written by the caller once the chunks before them are.
    ``stream`` must be buffered (every write whole), at its start, and written by no one else. Not
    thread-safe: one caller.
    """

    def __init__(self, stream: BinaryIO, *, chunk_size: int = 1024 * 1024) -> None:
        self._stream = stream
        self._chunk_size = chunk_size
        self._offset = 0  # where the next byte goes in the file (the writing thread's count)
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._statistics = Statistics(
            attachment_count=0,
            channel_count=0,
            channel_message_counts={},
            chunk_count=0,
            message_count=0,
            metadata_count=0,
            message_start_time=0,
            message_end_time=0,
            schema_count=0,
        )
        self._chunk_indexes: list[ChunkIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._new_chunk()
        self._pool = threads_in_this_context(1, "rose-mcap-writer")
        self._queued: deque[Future[None]] = deque()

    # The chunk being filled: its records' bytes in pieces (joined once, by the writing thread),
    # and per channel, in order of first use, the (log time, offset) of each of its messages.
    def _new_chunk(self) -> None:
        self._pieces: list[bytes] = []
        self._chunk_bytes = 0
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0
        self._message_offsets: dict[int, list[tuple[int, int]]] = {}

    def start(self, profile: str = "", library: str = "") -> None:
        """The magic and the header record."""
        builder = RecordBuilder()
        Header(profile, library).write(builder)
        record = MCAP_MAGIC + builder.end()
        self._submit(lambda: self._write(record))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """A schema, into the chunk being filled; returns its id (1, 2, ...)."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas[schema.id] = schema
        self._statistics.schema_count += 1
        self._add_record(schema)
        return schema.id

    def register_channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]
    ) -> int:
        """A channel, into the chunk being filled; returns its id (1, 2, ...)."""
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=metadata,
        )
        self._channels[channel.id] = channel
        self._statistics.channel_count += 1
        self._add_record(channel)
        return channel.id

    def add_message(
        self,
        channel_id: int,
        log_time: int,
        data: bytes | memoryview,
        publish_time: int,
        sequence: int = 0,
    ) -> None:
        """A message record, into the chunk being filled (``data`` copied unless ``bytes``)."""
        stats = self._statistics
        if stats.message_count == 0:
            stats.message_start_time = log_time
        else:
            stats.message_start_time = min(log_time, stats.message_start_time)
        stats.message_end_time = max(log_time, stats.message_end_time)
        counts = stats.channel_message_counts
        counts[channel_id] = counts.get(channel_id, 0) + 1
        stats.message_count += 1

        if self._chunk_messages == 0:
            self._chunk_start = log_time
        else:
            self._chunk_start = min(self._chunk_start, log_time)
        self._chunk_end = max(self._chunk_end, log_time)
        offsets = self._message_offsets.get(channel_id)
        if offsets is None:
            offsets = self._message_offsets[channel_id] = []
        offsets.append((log_time, self._chunk_bytes))
        self._chunk_messages += 1
        # Bytes are kept as they are; a view (of a reader's buffer) is copied, as the library's
        # record builder copies every message.
        body = data if isinstance(data, bytes) else bytes(data)
        self._pieces.append(
            _MESSAGE_HEADER.pack(
                Opcode.MESSAGE,
                _MESSAGE_FIELDS_BYTES + len(body),
                channel_id,
                sequence,
                log_time,
                publish_time,
            )
        )
        self._pieces.append(body)
        self._chunk_bytes += _MESSAGE_HEADER.size + len(body)
        self._maybe_finish_chunk()

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record, in the data section at this point (not in a chunk)."""
        self._statistics.metadata_count += 1
        builder = RecordBuilder()
        Metadata(name=name, metadata=data).write(builder)
        self._wait(0)  # the chunks before it written: this thread writes it
        self._metadata_indexes.append(
            MetadataIndex(offset=self._offset, length=builder.count, name=name)
        )
        self._write(builder.end())

    def add_attachment(
        self, create_time: int, log_time: int, name: str, media_type: str, data: bytes
    ) -> None:
        """An attachment record, in the data section at this point (not in a chunk). Written by
        this thread once the chunks before it are: attachments can be gigabytes, and queued
        they were held two or three at a time."""
        self._statistics.attachment_count += 1
        builder = RecordBuilder()
        Attachment(
            create_time=create_time,
            log_time=log_time,
            name=name,
            media_type=media_type,
            data=data,
        ).write(builder)
        self._wait(0)
        self._attachment_indexes.append(
            AttachmentIndex(
                offset=self._offset,
                length=builder.count,
                create_time=create_time,
                log_time=log_time,
                data_size=len(data),
                name=name,
                media_type=media_type,
            )
        )
        self._write(builder.end())

    def finish(self) -> None:
        """The last chunk, the data end, the summary and the footer; then the thread ends. The
        stream is left open."""
        try:
            self._finish_chunk()
            self._wait(0)
        except BaseException:
            self.abort()
            raise
        self._pool.shutdown(wait=True)
        builder = RecordBuilder()
        DataEnd(0).write(builder)
        self._write(builder.end())
        self._write_summary()

    def abort(self) -> None:
        """Drop what is queued and end the thread (what it is writing, it finishes). Never raises
        the queued writes' errors."""
        for future in self._queued:
            future.cancel()
        self._queued.clear()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def _add_record(self, record: Schema | Channel) -> None:
        builder = RecordBuilder()
        record.write(builder)
        piece = builder.end()
        self._pieces.append(piece)
        self._chunk_bytes += len(piece)
        self._maybe_finish_chunk()

    def _maybe_finish_chunk(self) -> None:
        if self._chunk_bytes > self._chunk_size:
            self._finish_chunk()

    def _finish_chunk(self) -> None:
        """Hand the chunk being filled to the writing thread (a chunk without messages is not
        written: its schemas and channels go into the next one, as in the library)."""
        if self._chunk_messages == 0:
            return
        self._statistics.chunk_count += 1
        pieces, start, end = self._pieces, self._chunk_start, self._chunk_end
        offsets = self._message_offsets
        self._new_chunk()
        self._submit(lambda: self._write_chunk(pieces, start, end, offsets))

    def _write_chunk(
        self,
        pieces: list[bytes],
        start: int,
        end: int,
        offsets: dict[int, list[tuple[int, int]]],
    ) -> None:
        """(The writing thread.) The chunk record, its message indexes and its chunk index."""
        data = b"".join(pieces)
        compressed = zstandard.compress(data)
        builder = RecordBuilder()
        Chunk(
            compression="zstd",
            data=compressed,
            message_start_time=start,
            message_end_time=end,
            uncompressed_crc=crc32(data),
            uncompressed_size=len(data),
        ).write(builder)
        chunk_record = builder.end()
        index = ChunkIndex(
            message_start_time=start,
            message_end_time=end,
            chunk_start_offset=self._offset,
            chunk_length=len(chunk_record),
            message_index_offsets={},
            message_index_length=0,
            compression="zstd",
            compressed_size=len(compressed),
            uncompressed_size=len(data),
        )
        self._write(chunk_record)
        for channel_id, records in offsets.items():
            index.message_index_offsets[channel_id] = self._offset + builder.count
            MessageIndex(channel_id=channel_id, records=records).write(builder)
        index.message_index_length = builder.count
        self._write(builder.end())
        self._chunk_indexes.append(index)

    def _write_summary(self) -> None:
        """The summary (schemas, channels, statistics, chunk, attachment and metadata indexes, in
        groups), its offsets, the footer and the closing magic."""
        summary_start = self._offset
        builder = RecordBuilder()
        offsets = []
        groups: list[tuple[Opcode, list[Callable[[RecordBuilder], None]]]] = [
            (Opcode.SCHEMA, [s.write for s in self._schemas.values()]),
            (Opcode.CHANNEL, [c.write for c in self._channels.values()]),
            (Opcode.STATISTICS, [self._statistics.write]),
            (Opcode.CHUNK_INDEX, [i.write for i in self._chunk_indexes]),
            (Opcode.ATTACHMENT_INDEX, [i.write for i in self._attachment_indexes]),
            (Opcode.METADATA_INDEX, [i.write for i in self._metadata_indexes]),
        ]
        for opcode, writes in groups:
            group_start = builder.count
            for write in writes:
                write(builder)
            offsets.append(
                SummaryOffset(
                    group_opcode=opcode,
                    group_start=summary_start + group_start,
                    group_length=builder.count - group_start,
                )
            )
        offsets_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        crc = crc32(
            _FOOTER_START.pack(Opcode.FOOTER, 8 + 8 + 4, summary_start, offsets_start),
            crc32(summary),
        )
        Footer(
            summary_start=summary_start, summary_offset_start=offsets_start, summary_crc=crc
        ).write(builder)
        self._write(summary + builder.end() + MCAP_MAGIC)

    def _write(self, data: bytes) -> None:
        self._stream.write(data)
        self._offset += len(data)

    def _submit(self, job: Callable[[], None]) -> None:
        """Queue ``job`` on the writing thread; raise the error of a job done, if any; wait while
        more than :data:`_QUEUED_CHUNKS` are queued. Run it here if the thread cannot start."""
        self._wait(_QUEUED_CHUNKS)
        try:
            self._queued.append(self._pool.submit(job))
        except RuntimeError:  # "can't start new thread" (the only start is the first submit)
            self._wait(0)
            job()

    def _wait(self, most: int) -> None:
        queued = self._queued
        while queued and (len(queued) > most or queued[0].done()):
            queued.popleft().result()  # raises the job's error
