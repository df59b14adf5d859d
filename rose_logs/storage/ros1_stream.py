"""What can be read of a ROS 1 bag from its start, when its index is missing or damaged.

A ``rosbag record`` that crashed or was killed leaves a ``.bag.active`` file: its bag header says
``index_pos = 0`` and the file ends in the middle of a chunk, with no index or connection records
after the chunks. rosbags (like ``rosbag`` itself) needs the index, so such a bag cannot be opened;
``rosbag reindex`` rebuilds it. For ``--salvage`` this backend reads the file record by record
instead (ROS bag format 2.0): every complete chunk is decompressed (none, bz2, lz4) and its
connection and message records are kept, up to the first record that cannot be read
(:attr:`Ros1StreamReadBackend.damage` says where and why).

Messages come in file order (the order they were recorded), not sorted by time. The file is read
twice, as :class:`rose_logs.storage.mcap.McapStreamReadBackend` does: :meth:`open` for the
connections and their counts, :meth:`messages` for the messages; memory stays that of one chunk.

A bag whose index is intact but a chunk damaged is read through its index instead
(:func:`chunk_messages`, :class:`Ros1IndexedReadBackend`): every chunk its chunk infos list, in
log-time order, the damaged ones skipped and said.
"""

from __future__ import annotations

import bisect
import bz2
import dataclasses
import heapq
import io
import itertools
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from rose.limits import short
from rose_logs.errors import storage_failure
from rose_logs.storage.connections import QosStyle
from rose_logs.storage.mcap import SkippedChunk
from rose_logs.storage.records import Channel, RawMessage, normalize_msgtype

__all__ = [
    "BagIndex",
    "ChunkInfo",
    "IndexDamage",
    "IndexMismatch",
    "Ros1IndexedReadBackend",
    "Ros1StreamReadBackend",
    "chunk_messages",
    "damaged_index",
    "decompressed_sizes",
    "first_damaged_chunk",
    "read_index",
    "unindexed_messages",
]

_MAGIC = b"#ROSBAG V2.0\n"
_OP_MESSAGE = 0x02
_OP_CHUNK = 0x05
_OP_CHUNK_INFO = 0x06
_OP_CONNECTION = 0x07
#: More connections than any recording has: a hostile file could otherwise make millions.
_MAX_CONNECTIONS = 65536
#: Largest chunk accepted, uncompressed (rosbag's chunks are 768 KiB by default; a chunk holds one
#: message at least: a map of --max-cells (1e8 cells) is 100 MB).
_MAX_CHUNK_BYTES = 256 << 20
#: Largest record read: a chunk of that size, stored, plus room for framing.
_MAX_RECORD_BYTES = _MAX_CHUNK_BYTES + (16 << 20)


class _Damage(Exception):
    """A record that cannot be read; the message says why."""


class _PastIndex(_Damage):
    """A record before the index whose data runs past the index."""


@dataclass(frozen=True)
class _Connection:
    conn: int
    topic: str
    msgtype: str
    md5sum: str
    definition: str
    callerid: str | None
    latching: int | None

    def channel(self, channel_id: int, message_count: int) -> Channel:
        """This connection as the reader's channel ``channel_id`` of ``message_count`` messages."""
        return Channel(
            id=channel_id,
            topic=self.topic,
            msgtype=normalize_msgtype(self.msgtype),
            message_encoding="ros1",
            msgdef=self.definition,
            msgdef_encoding="ros1msg" if self.definition else "",
            digest=self.md5sum,
            message_count=message_count,
            callerid=self.callerid,
            latching=self.latching,
        )


def _fields(block: bytes) -> dict[str, bytes]:
    """The ``name=value`` fields of a record header (or of a connection record's data)."""
    fields: dict[str, bytes] = {}
    pos = 0
    while pos < len(block):
        if pos + 4 > len(block):
            msg = "a header field is cut short"
            raise _Damage(msg)
        (length,) = struct.unpack_from("<I", block, pos)
        pos += 4
        if pos + length > len(block):
            msg = "a header field runs past its header"
            raise _Damage(msg)
        name, sep, value = block[pos : pos + length].partition(b"=")
        if not sep:
            msg = "a header field without '='"
            raise _Damage(msg)
        fields[name.decode("utf-8", "replace")] = value
        pos += length
    return fields


def _read_block(stream: BinaryIO, end: int, what: str, at: int | None = None) -> bytes:
    """A length-prefixed block (a record's header or data) that must end by byte ``end`` and hold
    at most :data:`_MAX_RECORD_BYTES` (checked before it is read). ``at``: the stream's position,
    where the caller knows it (a file's ``tell()`` is a system call)."""
    raw = stream.read(4)
    if len(raw) < 4:
        msg = f"the file ends inside a record's {what} length"
        raise _Damage(msg)
    (length,) = struct.unpack("<I", raw)
    if length > _MAX_RECORD_BYTES:
        msg = f"a record's {what} of {length} bytes, more than any chunk"
        raise _Damage(msg)
    if (stream.tell() if at is None else at + 4) + length > end:
        msg = f"a record's {what} ({length} bytes) runs past the end"
        raise _Damage(msg)
    block = stream.read(length)
    if len(block) < length:
        msg = f"the file ends inside a record's {what}"
        raise _Damage(msg)
    return block


def _read_record(stream: BinaryIO, end: int) -> tuple[dict[str, bytes], bytes] | None:
    """The next ``(header fields, data)`` record of ``stream``, which ends at byte ``end``; None
    there."""
    if stream.tell() >= end:
        return None
    header = _read_block(stream, end, "header")
    return _fields(header), _read_block(stream, end, "data")


def _op(fields: dict[str, bytes]) -> int:
    op = fields.get("op", b"")
    if len(op) != 1:
        msg = "a record without a valid op field"
        raise _Damage(msg)
    return op[0]


def _uint(fields: dict[str, bytes], name: str, fmt: str) -> int:
    try:
        return int(struct.unpack(fmt, fields[name])[0])
    except (KeyError, struct.error) as err:
        msg = f"a record without a valid {name} field"
        raise _Damage(msg) from err


def _connection(fields: dict[str, bytes], data: bytes) -> _Connection:
    info = _fields(data)
    try:
        topic = fields.get("topic", info.get("topic", b"")).decode("utf-8")
        msgtype = info["type"].decode("utf-8")
        md5sum = info.get("md5sum", b"").decode("ascii")
        definition = info.get("message_definition", b"").decode("utf-8")
        callerid = info["callerid"].decode("utf-8") if "callerid" in info else None
    except (KeyError, UnicodeDecodeError) as err:
        msg = "a connection record without a readable topic or type"
        raise _Damage(msg) from err
    flag = info.get("latching", b"").strip()  # as rosbags reads it: a number, else none
    latching = int(flag) if flag.isdigit() else None
    return _Connection(
        _uint(fields, "conn", "<I"), topic, msgtype, md5sum, definition, callerid, latching
    )


def _decompress(fields: dict[str, bytes], data: bytes, *, exact: bool = True) -> bytes:
    """A chunk's content: at most the size its header declares, so that a hostile chunk cannot
    expand without bound (a few KB of bz2 can declare gigabytes). ``exact=False`` (a chunk the
    index locates, whose records are then all parsed): a damaged size field is no damage, the
    content is bounded by the largest chunk instead."""
    compression = fields.get("compression", b"none").decode("ascii", "replace")
    size = _uint(fields, "size", "<I") if exact else _MAX_CHUNK_BYTES
    if size > _MAX_CHUNK_BYTES:
        msg = f"a chunk of {size} bytes, more than {_MAX_CHUNK_BYTES}"
        raise _Damage(msg)
    try:
        if compression == "none":
            content = data
        elif compression == "bz2":
            content = bz2.BZ2Decompressor().decompress(data, max_length=size)
        elif compression == "lz4":
            from lz4.frame import LZ4FrameDecompressor  # type: ignore[import-untyped]

            content = bytes(LZ4FrameDecompressor().decompress(data, max_length=size))
        else:
            msg = f"a chunk compressed with unknown {compression!r}"
            raise _Damage(msg)
    except (OSError, ValueError, RuntimeError, EOFError) as err:
        msg = f"a {compression} chunk that does not decompress ({short(err, 80)})"
        raise _Damage(msg) from err
    if exact and len(content) != size:
        msg = f"a {compression} chunk of {len(content)} bytes that declares {size}"
        raise _Damage(msg)
    return content


class _Ros1FileBackend:
    """What the two ``--salvage`` readers of a ROS 1 bag share: its channels as they are found, its
    time range, and the open file (:meth:`close`)."""

    profile = ""
    format = "ros1"

    def __init__(self, path: Path) -> None:
        self.path = path
        self.channels: tuple[Channel, ...] = ()
        self._by_conn: dict[int, Channel] = {}
        self.start_ns = 0
        self.end_ns = 0
        self.qos_style: QosStyle | None = None
        self.stream: BinaryIO | None = None

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None


class Ros1StreamReadBackend(_Ros1FileBackend):
    """A ROS 1 bag read from its start without its index (see module notes). For ``--salvage`` only.

    Attributes
    ----------
    damage : str
        Where reading stopped and why, once :meth:`open` has run.
    complete : bool
        Whether every record could be read and the index records were there (only the bag header's
        pointer to them was wrong): then nothing was lost.
    """

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.damage = ""
        self.complete = False
        self._end: int | None = None  # where open() stopped: messages() stops there too
        #: Messages whose time disagrees with their index entry's, left out (:meth:`_timed`).
        self.mistimed = 0
        self.skipped_chunks: list[SkippedChunk] = []

    def _items(self) -> Iterator[_Connection | tuple[int, int, bytes]]:
        """Connections and ``(conn, time ns, data)`` messages in file order, complete chunks only,
        up to the first unreadable record (which sets :attr:`damage`) or where :meth:`open` stopped
        (a recording still growing has more by the second pass)."""
        assert self.stream is not None
        self.stream.seek(0)
        size = self.path.stat().st_size if self._end is None else self._end
        if self.stream.read(len(_MAGIC)) != _MAGIC:
            self.damage = "not a ROS bag 2.0 file"
            return
        indexed = False
        known: set[int] = set()  # connection ids seen
        while True:
            offset = self.stream.tell()
            try:
                record = _read_record(self.stream, size)
                if record is None:
                    break
                fields, data = record
                op = _op(fields)
                if op == _OP_CHUNK:
                    content = _decompress(fields, data)
                    # A chunk counts only when all of it reads: checked before anything is handed
                    # out, without keeping its records (a chunk may hold millions of tiny ones).
                    for item in _chunk_items(content):
                        _count_connection(item, known)
                    entries = _entries_after(self.stream, size)
                    items: Iterator[_Connection | tuple[int, int, bytes]] = self._timed(
                        content, entries, offset, size
                    )
                else:
                    # Chunk infos come only in the index section after the last chunk (index data
                    # records follow every chunk, so they prove nothing).
                    indexed |= op == _OP_CHUNK_INFO
                    listed = list(_record_items(op, fields, data))
                    for item in listed:
                        _count_connection(item, known)
                    items = iter(listed)
            except _Damage as err:
                self.damage = f"unreadable from byte {offset} of {size}: {err}"
                self._end = offset
                return
            yield from items
        self._end = size
        self.complete = indexed and not self.mistimed
        if not self.damage:
            self.damage = (
                "the bag's index is damaged or misplaced; every record was read"
                if indexed
                else "no index at the end (the recording was not closed)"
            )

    def _timed(
        self, content: bytes, entries: dict[tuple[int, int], int], pos: int, size: int
    ) -> Iterator[_Connection | tuple[int, int, bytes]]:
        """The items of a chunk (its ``content``, at byte ``pos`` of ``size``) but its messages
        whose time is damaged: one that disagrees with its index entry's (``entries``,
        :func:`_entries_after`) and lies farther than that entry's time from the times of the
        chunk's messages that agree with theirs (a bit flipped in the message, 2106 in a session
        of 2023, which then spanned 83 years), said in :attr:`skipped_chunks` (as the chunk
        reader says a message outside its chunk's times) and counted in :attr:`mistimed`. A
        message whose entry is the damaged one is kept, as the indexed reading keeps it."""
        agreed: tuple[int, int] | None = None  # found at the first disagreement
        for at, item in _chunk_items_at(content):
            if not isinstance(item, _Connection):
                listed = entries.get((item[0], at), item[1])
                if listed != item[1]:
                    if agreed is None:
                        agreed = _agreed_times(content, entries) or (listed, listed)
                    if _off(item[1], agreed) <= _off(listed, agreed):  # the entry is damaged
                        yield item
                        continue
                    if self._end is None:  # open()'s pass
                        self.mistimed += 1
                    else:  # messages()': said once it is read
                        channel = self._by_conn.get(item[0])
                        reason = (
                            f"a message on {channel.topic if channel else '?'} at {item[1]} ns, "
                            f"its index entry says {listed} ns: its time is damaged"
                        )
                        self.skipped_chunks.append(
                            SkippedChunk(pos, size, reason, item[1], item[1], one_message=True)
                        )
                    continue
            yield item

    def open(self) -> None:
        self.stream = self.path.open("rb")
        connections: dict[int, _Connection] = {}
        counts: dict[int, int] = {}
        first = last = None
        for item in self._items():
            if isinstance(item, _Connection):
                connections.setdefault(item.conn, item)
            else:
                conn, time_ns, _ = item
                counts[conn] = counts.get(conn, 0) + 1
                first = time_ns if first is None else min(first, time_ns)
                last = time_ns if last is None else max(last, time_ns)
        orphans = {conn: n for conn, n in counts.items() if conn not in connections}
        if orphans:
            # Their connection record would have come after the damage (or never did).
            self.damage += (
                f"; {sum(orphans.values())} messages on {len(orphans)} connections whose "
                "connection record is missing, left out"
            )
            self.complete = False
        channels: list[Channel] = []
        for conn, c in connections.items():
            channel = c.channel(len(channels), counts.get(conn, 0))
            channels.append(channel)
            self._by_conn[conn] = channel
        self.channels = tuple(channels)
        if first is not None and last is not None:
            self.start_ns, self.end_ns = first, last

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        by_conn = self._by_conn
        for item in self._items():
            if isinstance(item, _Connection):
                continue
            conn, time_ns, data = item
            channel = by_conn.get(conn)
            if channel is not None and (topics is None or channel.topic in topics):
                yield RawMessage(channel, time_ns, data, time_ns)


def _count_connection(item: _Connection | tuple[int, int, bytes], known: set[int]) -> None:
    """Note a connection record's id; more than :data:`_MAX_CONNECTIONS` ids are damage."""
    if isinstance(item, _Connection) and item.conn not in known:
        if len(known) >= _MAX_CONNECTIONS:
            msg = f"more than {_MAX_CONNECTIONS} connections"
            raise _Damage(msg)
        known.add(item.conn)


def _record_items(
    op: int, fields: dict[str, bytes], data: bytes
) -> Iterator[_Connection | tuple[int, int, bytes]]:
    """The connection or message of one record (other records: bag header, index, chunk info)."""
    if op == _OP_CONNECTION:
        yield _connection(fields, data)
    elif op == _OP_MESSAGE:
        time = fields.get("time", b"")
        if len(time) != 8:
            msg = "a message record without a valid time field"
            raise _Damage(msg)
        sec, nsec = struct.unpack("<II", time)
        yield _uint(fields, "conn", "<I"), sec * 1_000_000_000 + nsec, data


def _chunk_items(content: bytes) -> Iterator[_Connection | tuple[int, int, bytes]]:
    """The connections and messages inside a decompressed chunk."""
    for _, item in _chunk_items_at(content):
        yield item


def _chunk_items_at(content: bytes) -> Iterator[tuple[int, _Connection | tuple[int, int, bytes]]]:
    """The connections and messages inside a decompressed chunk, each with the byte of
    ``content`` where its record starts (what an index entry gives)."""
    stream = io.BytesIO(content)
    while True:
        at = stream.tell()
        record = _read_record(stream, len(content))
        if record is None:
            return
        fields, data = record
        for item in _record_items(_op(fields), fields, data):
            yield at, item


def _agreed_times(content: bytes, entries: dict[tuple[int, int], int]) -> tuple[int, int] | None:
    """The earliest and latest time (ns) of the messages inside a decompressed chunk whose time
    is their index entry's (``entries``, :func:`_entries_after`); None: no such message."""
    times = [
        item[1]
        for at, item in _chunk_items_at(content)
        if not isinstance(item, _Connection) and entries.get((item[0], at)) == item[1]
    ]
    return (min(times), max(times)) if times else None


def _off(time_ns: int, span: tuple[int, int]) -> int:
    """How far ``time_ns`` lies outside ``span`` (first, last, ns): 0 within it."""
    return max(span[0] - time_ns, time_ns - span[1], 0)


def _entries_after(stream: BinaryIO, size: int) -> dict[tuple[int, int], int]:
    """The time (ns) of each message the index data records at ``stream`` (after a chunk)
    give, by its connection and its byte in the chunk; ``stream`` is left after them, at the
    first other record (or one that does not read, which the walk then reads as before)."""
    entries: dict[tuple[int, int], int] = {}
    while True:
        at = stream.tell()
        try:
            record = _read_record(stream, size)
            if record is None or _op(record[0]) != _OP_INDEX_DATA:
                stream.seek(at)
                return entries
            fields, data = record
            conn = _uint(fields, "conn", "<I")
        except _Damage:
            stream.seek(at)
            return entries
        whole = len(data) - len(data) % 12
        for sec, nsec, offset in struct.iter_unpack("<III", data[:whole]):
            entries[(conn, offset)] = sec * 1_000_000_000 + nsec


_OP_INDEX_DATA = 0x04


def _bag_header(
    stream: BinaryIO, size: int, first_chunk: int | None
) -> tuple[dict[str, bytes], bytes] | None:
    """The bag header record (``stream`` is past the magic line), ``stream`` left after it.

    ``first_chunk``: where the index places the first chunk. The header's data is padding (to
    byte 4109 in a bag rosbag wrote): when its length is damaged (past the file, ending past
    that chunk, or ending short of it inside the padding, where no record starts), the walk goes
    on from that chunk, as it does past a damaged chunk, instead of failing at the bag's first
    record (``--salvage`` said the bag could not be read, though its index and every chunk were
    intact). None: a damaged length is damage (the first error)."""
    if first_chunk is None:
        return _read_record(stream, size)
    fields = _fields(_read_block(stream, size, "header"))
    raw = stream.read(4)
    (length,) = struct.unpack("<I", raw) if len(raw) == 4 else (size,)
    end = stream.tell() + length
    if end > first_chunk or (end < first_chunk and not _record_at(stream, end, first_chunk)):
        stream.seek(first_chunk)
        return fields, b""
    return fields, stream.read(length)


def _record_at(stream: BinaryIO, at: int, end: int) -> bool:
    """Whether a chunk or index data record (what lies between the bag header and the index)
    starts at byte ``at``, its header ending by byte ``end``; ``stream`` is left where it was."""
    was = stream.tell()
    try:
        stream.seek(at)
        return _op(_fields(_read_block(stream, end, "header"))) in (_OP_CHUNK, _OP_INDEX_DATA)
    except _Damage:
        return False
    finally:
        stream.seek(was)


def unindexed_messages(
    path: Path,
    listed: dict[int, dict[int, int]],
    *,
    connections: set[int] | None = None,
    skip_damaged_chunks: bool = False,
) -> str | None:
    """What the index of the ROS 1 bag ``path`` leaves out, in a few words; None when it accounts
    for every chunk and message.

    ``listed`` maps each chunk's position to the messages its chunk info counts per connection.
    The records from the bag header to the index are walked (their headers only: a chunk's data
    is skipped), and the index data records after each chunk (which locate its messages, per
    connection) are counted. A chunk info whose count was damaged, an index data record naming
    another connection, or a bag header that counts fewer chunks than the file holds, loses
    messages silently otherwise: a reader reads what the index lists.

    ``connections``: the ids of the index's connection records. Messages the chunk infos count
    of a connection without one (its id damaged) are left out by a reader, which knows no topic
    for them.

    ``skip_damaged_chunks``: a listed chunk whose record cannot be read (a damaged header, a data
    length past the next listed chunk), or one of whose index data records cannot, is taken as
    its chunk info counts it, and the walk goes on from the next listed chunk (a reader through
    the chunk infos reads the chunk itself, or says it lost it).
    """
    found: dict[int, dict[int, int]] = {}
    size = path.stat().st_size
    starts = sorted(listed)
    with path.open("rb") as stream:
        stream.readline()  # the magic line (checked by whoever opened the bag)
        try:
            first_chunk = starts[0] if skip_damaged_chunks and starts else None
            header = _bag_header(stream, size, first_chunk)
            index_pos = _uint(header[0], "index_pos", "<Q") if header is not None else 0
            chunk: dict[int, int] | None = None
            chunk_at = -1  # where the chunk ``chunk`` counts the index entries of starts
            # The position is followed here, not asked of the file (tell() is a system call, and
            # this runs for every record: a chunk and an index data record per topic in it).
            at = stream.tell()
            while at < index_pos:
                # The next listed chunk's place (a bisection: a slice of the places after each
                # record cost a copy per record, chunks x records on a bag of many topics).
                after = bisect.bisect_right(starts, at)
                following = min(starts[after], index_pos) if after < len(starts) else index_pos
                # A chunk's record ends before the next listed chunk, or the index.
                bound = following if at in listed else index_pos
                try:
                    block = _read_block(stream, bound, "header", at)
                    fields = _fields(block)
                    raw = stream.read(4)
                    (length,) = struct.unpack("<I", raw) if len(raw) == 4 else (index_pos,)
                    data_at = at + 4 + len(block) + len(raw)  # where stream.tell() is
                    if data_at + length > bound:
                        if at in listed:
                            msg = f"a chunk at byte {at} runs past the next record"
                            raise _Damage(msg)
                        msg = f"a record at byte {at} runs past the index at byte {index_pos}"
                        raise _PastIndex(msg)
                    op = _op(fields)
                    if at in listed and op != _OP_CHUNK:
                        msg = f"no chunk record at byte {at}"
                        raise _Damage(msg)
                    if op == _OP_CHUNK:
                        chunk, chunk_at = found.setdefault(at, {}), at
                    elif op == _OP_INDEX_DATA and chunk is not None:
                        conn = _uint(fields, "conn", "<I")
                        chunk[conn] = chunk.get(conn, 0) + _uint(fields, "count", "<I")
                    at = stream.seek(data_at + length)
                except _Damage:
                    owner = at if at in listed else chunk_at if chunk is not None else None
                    if not skip_damaged_chunks or owner is None:
                        raise
                    # A damaged chunk, or index entries of one: what its chunk info counts.
                    found[owner] = dict(listed[owner])
                    chunk = None
                    at = stream.seek(following)
        except _PastIndex as err:
            return str(err)
        except _Damage as err:
            return f"{err} before the index"
    unlisted = sorted(set(found) - set(listed))
    if unlisted:
        lost = sum(sum(found[pos].values()) for pos in unlisted)
        return (
            f"{len(unlisted)} chunk(s) from byte {unlisted[0]} on, with {lost} message(s), are "
            "not in the index"
        )
    for pos, counts in sorted(found.items()):
        declared = {conn: n for conn, n in listed[pos].items() if n}
        counts = {conn: n for conn, n in counts.items() if n}
        if counts != declared:
            return (
                f"the chunk at byte {pos} has index entries for {sum(counts.values())} "
                f"message(s) (connections {_ids(counts)}), its chunk info counts "
                f"{sum(declared.values())} (connections {_ids(declared)})"
            )
    if connections is not None:
        orphans: dict[int, int] = {}
        for counts in listed.values():
            for conn, n in counts.items():
                if n and conn not in connections:
                    orphans[conn] = orphans.get(conn, 0) + n
        if orphans:
            return (
                f"its chunk infos count {sum(orphans.values())} message(s) of connections "
                f"{_ids(orphans)}, which it holds no connection record of (connections "
                f"{_ids(dict.fromkeys(connections, 1))})"
            )
    return None


def _ids(counts: dict[int, int]) -> str:
    return ", ".join(str(conn) for conn in sorted(counts)) or "none"


# -- reading through the index, around damaged chunks ------------------------------------------------


class IndexDamage(Exception):
    """The index section of a ROS 1 bag (its connection and chunk info records) cannot be read.

    ``in_index``: the bag header was read and places its index inside the file (a bag that was
    closed), so the damage is in the index's records; False when there is no index to read (a
    recording that was not closed, a file cut short before it, or no bag header).
    """

    def __init__(self, problem: str, *, in_index: bool = False) -> None:
        super().__init__(problem)
        self.in_index = in_index


def damaged_index(problem: str, *, through_chunk_infos: bool) -> str:
    """A ROS 1 bag's damaged index in words (``problem``: what is wrong) and what ``--salvage``
    does then: reads the bag through its chunk infos (they are intact) or record by record."""
    how = "chunk by chunk through its chunk infos" if through_chunk_infos else "record by record"
    return f"the bag's index is damaged ({problem}); --salvage reads the bag {how}"


@dataclass(frozen=True)
class ChunkInfo:
    """A chunk as the bag's index lists it (its chunk info record)."""

    pos: int  # byte of the file where the chunk record starts
    start_ns: int  # log times of its first and last message
    end_ns: int
    counts: dict[int, int]  # messages per connection id


@dataclass(frozen=True)
class BagIndex:
    """What the index section at the end of a ROS 1 bag says: its connections (in the index's
    order, the order rosbags reads them in) and chunks (in the index's order)."""

    size: int  # bytes of the file
    index_pos: int
    connections: tuple[_Connection, ...]
    chunks: tuple[ChunkInfo, ...]
    starts: tuple[int, ...]  # the chunks' positions, sorted

    def chunk_end(self, chunk: ChunkInfo) -> int:
        """Where the record of ``chunk`` must end at the latest: the next chunk, else the index."""
        after = bisect.bisect_right(self.starts, chunk.pos)
        return self.starts[after] if after < len(self.starts) else self.index_pos


def entry_spans(stream: BinaryIO, index: BagIndex) -> dict[int, tuple[int, int]]:
    """The first and last message time (ns) of each chunk of ``index`` (by its byte position)
    as the index data records after it give them (their entries' times); none for a chunk
    whose record or records do not read. The chunks' data is skipped, not read."""
    spans: dict[int, tuple[int, int]] = {}
    for chunk in index.chunks:
        end = index.chunk_end(chunk)
        try:
            stream.seek(chunk.pos)
            _read_block(stream, end, "header")
            raw = stream.read(4)
            if len(raw) < 4:
                continue
            stream.seek(struct.unpack("<I", raw)[0], io.SEEK_CUR)
        except (_Damage, OSError):
            continue
        times = _entries_after(stream, end).values()
        try:
            # Where they stopped: the next chunk, or the index. A record of them that does not
            # read leaves the chunk's entries partly known: their span (a connection's last
            # message left out) would cut the chunk's times short.
            _read_record(stream, end)
        except (_Damage, OSError):
            continue
        if times:
            spans[chunk.pos] = (min(times), max(times))
    return spans


def read_index(path: Path) -> BagIndex:
    """The index of the ROS 1 bag ``path`` (its records read, not the chunks they point to).

    Raises
    ------
    IndexDamage
        When the bag header or a record of the index cannot be read, or the index points outside
        the file.
    """
    size = path.stat().st_size
    in_index = False
    try:
        with path.open("rb") as stream:
            if stream.read(len(_MAGIC)) != _MAGIC:
                msg = "not a ROS bag 2.0 file"
                raise _Damage(msg)
            if stream.tell() >= size:
                msg = "no bag header"
                raise _Damage(msg)
            header = _fields(_read_block(stream, size, "header"))
            # Its data is padding, which rosbags does not read either: a damaged length of it is
            # no damage of the index (unindexed_messages walks on from the first chunk).
            stream.seek(4, io.SEEK_CUR)
            index_pos = _uint(header, "index_pos", "<Q")
            conn_count = _uint(header, "conn_count", "<I")
            chunk_count = _uint(header, "chunk_count", "<I")
            if not stream.tell() <= index_pos < size:
                msg = f"the bag header places its index at byte {index_pos}, outside the file"
                raise _Damage(msg)
            if conn_count > _MAX_CONNECTIONS:
                msg = f"more than {_MAX_CONNECTIONS} connections"
                raise _Damage(msg)
            stream.seek(index_pos)
            in_index = True
            connections = []
            for _ in range(conn_count):
                fields, data = _index_record(stream, size, _OP_CONNECTION)
                connections.append(_connection(fields, data))
            chunks = []
            for _ in range(chunk_count):
                fields, data = _index_record(stream, size, _OP_CHUNK_INFO)
                chunks.append(_chunk_info(fields, data, index_pos))
    except (_Damage, OSError) as err:
        raise IndexDamage(str(err), in_index=in_index and isinstance(err, _Damage)) from err
    starts = tuple(sorted({c.pos for c in chunks}))
    return BagIndex(size, index_pos, tuple(connections), tuple(chunks), starts)


def _index_record(stream: BinaryIO, end: int, op: int) -> tuple[dict[str, bytes], bytes]:
    record = _read_record(stream, end)
    if record is None or _op(record[0]) != op:
        msg = f"a record of the index at byte {stream.tell()} is not what its bag header counts"
        raise _Damage(msg)
    return record


def _chunk_info(fields: dict[str, bytes], data: bytes, index_pos: int) -> ChunkInfo:
    pos = _uint(fields, "chunk_pos", "<Q")
    count = _uint(fields, "count", "<I")
    if pos >= index_pos or len(data) != 8 * count:
        msg = (
            f"a chunk info of a chunk at byte {pos}, or of {count} connections in {len(data)} bytes"
        )
        raise _Damage(msg)
    times = []
    for name in ("start_time", "end_time"):
        time = fields.get(name, b"")
        if len(time) != 8:
            msg = f"a chunk info without a valid {name} field"
            raise _Damage(msg)
        sec, nsec = struct.unpack("<II", time)
        times.append(sec * 1_000_000_000 + nsec)
    counts = dict(struct.iter_unpack("<II", data))
    return ChunkInfo(pos, times[0], times[1], counts)


class IndexMismatch(ValueError):
    """A chunk's index data records do not match the messages they point to (a strict reading,
    as rosbags', refuses the bag)."""


def read_chunk(
    stream: BinaryIO,
    index: BagIndex,
    chunk: ChunkInfo,
    conns: set[int] | None = None,
    *,
    strict: bool = False,
) -> list[tuple[int, int, bytes]]:
    """The ``(connection id, time ns, data)`` messages of the chunk ``chunk``, in file order: all
    of them, or at least those of the connections ``conns``.

    With ``conns``, the chunk's index data records (after it in the file) locate their messages,
    and only those are parsed (a map among thousands of scans); when they are missing or disagree
    with the chunk, every record is parsed instead, or, ``strict``, :class:`IndexMismatch` is
    raised (what rosbags reads through is damaged: a flipped byte in a message's time gave it
    another time, silently).

    Raises
    ------
    ValueError
        When its record, its decompression or one of its records fails (the message says how).
    """
    try:
        stream.seek(chunk.pos)
        end = index.chunk_end(chunk)
        record = _read_record(stream, end)
        if record is None or _op(record[0]) != _OP_CHUNK:
            msg = "no chunk record where the index points"
            raise _Damage(msg)
        content = _decompress(*record, exact=False)
        if conns is not None:
            located = _indexed_messages(stream, end, chunk, conns, content)
            if located is not None:
                return located
            if strict:
                msg = f"in the chunk at byte {chunk.pos} of {index.size}"
                raise IndexMismatch(msg)
        return [item for item in _chunk_items(content) if not isinstance(item, _Connection)]
    except (_Damage, OSError) as err:
        raise ValueError(str(err)) from err


def _indexed_messages(
    stream: BinaryIO, end: int, chunk: ChunkInfo, conns: set[int], content: bytes
) -> list[tuple[int, int, bytes]] | None:
    """The messages of ``conns`` in ``content`` (a chunk's data), in file order, where the index
    data records that follow the chunk (``stream`` is at the first) say they are; None when those
    records are missing, damaged, or do not match the chunk info's counts or the records they
    point to."""
    wanted = {conn for conn, n in chunk.counts.items() if n and conn in conns}
    offsets: list[tuple[int, int, int]] = []  # where, connection id, time (ns)
    seen: set[int] = set()
    try:
        while wanted - seen:
            record = _read_record(stream, end)
            if record is None or _op(record[0]) != _OP_INDEX_DATA:
                return None
            fields, data = record
            conn = _uint(fields, "conn", "<I")
            count = _uint(fields, "count", "<I")
            if conn in wanted:
                if conn in seen or count != chunk.counts[conn] or len(data) != 12 * count:
                    return None
                seen.add(conn)
                offsets.extend(
                    (offset, conn, sec * 1_000_000_000 + nsec)
                    for sec, nsec, offset in struct.iter_unpack("<III", data)
                )
        offsets.sort()
        if any(a[0] == b[0] for a, b in itertools.pairwise(offsets)):
            return None  # two entries at one record: a damaged offset
        messages = []
        view = io.BytesIO(content)
        for offset, conn, time_ns in offsets:
            view.seek(offset)
            record = _read_record(view, len(content))
            if record is None or _op(record[0]) != _OP_MESSAGE:
                return None
            item = next(_record_items(_OP_MESSAGE, *record))
            if not isinstance(item, tuple) or item[:2] != (conn, time_ns):
                return None
            if not record_follows(view, len(content)):
                return None
            messages.append(item)
    except _Damage:
        return None
    return messages


def decompressed_sizes(
    path: Path, index: BagIndex, chunks: Iterable[ChunkInfo]
) -> list[int] | None:
    """Bytes of each of ``chunks``' data once decompressed (its chunk record header's ``size``;
    a chunk's stored bytes can be a hundredth of it, a map's zeros in bz2); None when a chunk's
    header does not read. Only the headers are read."""
    sizes = []
    try:
        with path.open("rb") as stream:
            for chunk in chunks:
                stream.seek(chunk.pos)
                fields = _fields(_read_block(stream, index.chunk_end(chunk), "header"))
                if _op(fields) != _OP_CHUNK:
                    return None
                sizes.append(_uint(fields, "size", "<I"))
    except (_Damage, OSError):
        return None
    return sizes


def record_follows(view: BinaryIO, size: int) -> bool:
    """Whether a message or connection record starts where ``view`` (a chunk's data of ``size``
    bytes, just past a message record) is, or the data ends there. A damaged data length ends the
    record early or late: the next record (read in full, not only where the index points) would
    not start where this one ends. ``view`` is left past that record's header."""
    if view.tell() >= size:
        return view.tell() == size
    try:  # its header is enough (not a map's megabyte)
        return _header_op(_read_block(view, size, "header")) in (_OP_MESSAGE, _OP_CONNECTION)
    except _Damage:
        return False


def _header_op(block: bytes) -> int:
    """``_op(_fields(block))`` of a record header, the same checks made, without building its
    fields: called once per message a bag's reader hands out, that took as long as the reading."""
    op = b""
    pos, end = 0, len(block)
    while pos < end:
        if pos + 4 > end:
            msg = "a header field is cut short"
            raise _Damage(msg)
        (length,) = struct.unpack_from("<I", block, pos)
        pos += 4
        if pos + length > end:
            msg = "a header field runs past its header"
            raise _Damage(msg)
        equals = block.find(b"=", pos, pos + length)
        if equals < 0:
            msg = "a header field without '='"
            raise _Damage(msg)
        if block[pos:equals] == b"op":
            op = block[equals + 1 : pos + length]
        pos += length
    if len(op) != 1:
        msg = "a record without a valid op field"
        raise _Damage(msg)
    return op[0]


def chunk_messages(
    stream: BinaryIO,
    index: BagIndex,
    conns: set[int],
    skipped: list[SkippedChunk] | None,
) -> Iterator[tuple[int, int, bytes]]:
    """The ``(connection id, time ns, data)`` messages of the connections ``conns``, chunk by
    chunk through ``index``, in rosbags' order: log time, then the connection's place in the index,
    then the chunk's, then the message's place in its chunk.

    Each chunk is read when its first message's time comes (memory: the chunks that overlap in
    time, one for a recording). ``skipped``: a chunk that cannot be read is said there and skipped;
    None: its ValueError is raised, also where the index entries do not match the messages, as
    rosbags refuses them (:class:`IndexMismatch`).
    """
    rank = {c.conn: k for k, c in enumerate(index.connections)}
    tie = len(rank)  # messages of a connection the index does not list: left out (counted short)
    topics = {c.conn: c.topic for c in index.connections}
    # A chunk is read at its start (its end, where a damaged start comes after it): a start
    # damaged to a later time handed its messages out after the later chunks', out of order.
    queue: list[tuple[int, int, int, int, Any]] = [
        (min(chunk.start_ns, chunk.end_ns), -1, k, -1, chunk)
        for k, chunk in enumerate(index.chunks)
        if any(n and conn in conns for conn, n in chunk.counts.items())
    ]
    heapq.heapify(queue)
    while queue:
        _, _, k, place, item = heapq.heappop(queue)
        if place >= 0:
            yield item
            continue
        try:
            messages = read_chunk(stream, index, item, conns, strict=skipped is None)
        except ValueError as err:
            failed = storage_failure(err)
            if failed is not None:  # the disk under the bag failed, not its chunk: no damage
                raise failed from err
            if skipped is None:
                raise
            skipped.append(
                SkippedChunk(item.pos, index.size, short(str(err), 120), item.start_ns, item.end_ns)
            )
            continue
        for at, message in enumerate(messages):
            if message[0] not in conns:
                continue
            if skipped is not None and _outside(item, message[1]):
                reason = (
                    f"a message on {topics.get(message[0], '?')} at {message[1]} ns, outside "
                    f"the chunk's {item.start_ns}..{item.end_ns} ns: its time is damaged"
                )
                skipped.append(
                    SkippedChunk(
                        item.pos, index.size, reason, message[1], message[1], one_message=True
                    )
                )
                continue
            heapq.heappush(queue, (message[1], rank.get(message[0], tie), k, at, message))


def agreed_span(
    listed: tuple[int, int], entries: tuple[int, int] | None, *, widest: bool = True
) -> tuple[int, int]:
    """The times (first, last, ns) of a ROS 1 chunk from its chunk info's (``listed``) and its
    index entries' (``entries``; None: none noted), which a writer makes the same: either one
    whose start comes after its end is damaged and left out; of two that differ, ``widest``
    spans both (no message of either is judged outside it: reading), else the times both hold
    (a time damaged in one is left out: the log's range), or the chunk info's where they differ
    at both ends: one damaged time of the info moves one of its ends only, while an entry
    damaged past the other end (the chunk's first message's, to 2106) moves both of the
    entries' (the times both hold then lacked the chunk's first message)."""
    spans = [span for span in (listed, entries) if span is not None and span[0] <= span[1]]
    if not spans:
        return listed
    if widest:
        return min(first for first, _ in spans), max(last for _, last in spans)
    if len(spans) == 2 and spans[0][0] != spans[1][0] and spans[0][1] != spans[1][1]:
        return listed
    return max(first for first, _ in spans), min(last for _, last in spans)


def _outside(chunk: ChunkInfo, time_ns: int) -> bool:
    """Whether a message of ``chunk`` at ``time_ns`` lies outside the chunk's times, so that its
    time is damaged: a writer gives a chunk the times of its first and last message (a flipped
    bit gave a message of 2106 in a session of 2023, whose snapshots then spanned 83 years;
    without ``--salvage`` its index entry disagrees with it, and rosbags' reading refuses it).
    A chunk whose own times are damaged (its start after its end) judges none."""
    return chunk.start_ns <= chunk.end_ns and not chunk.start_ns <= time_ns <= chunk.end_ns


def first_damaged_chunk(path: Path, index: BagIndex, *, headers_only: bool) -> str | None:
    """Where and why the first chunk of ``index`` (in file order) that cannot be read is damaged,
    in a few words; None when every one reads. ``headers_only``: the chunk records' headers and
    lengths are checked, their data is not read."""
    with path.open("rb") as stream:
        for chunk in sorted(index.chunks, key=lambda c: c.pos):
            try:
                if headers_only:
                    stream.seek(chunk.pos)
                    fields = _fields(_read_block(stream, index.chunk_end(chunk), "header"))
                    if _op(fields) != _OP_CHUNK:
                        msg = "no chunk record where the index points"
                        raise _Damage(msg)
                    compression = fields.get("compression")
                    if compression not in (b"none", b"bz2", b"lz4"):
                        how = "no" if compression is None else f"unknown {compression!r}"
                        msg = f"a chunk with {how} compression"
                        raise _Damage(msg)
                    raw = stream.read(4)
                    length = struct.unpack("<I", raw)[0] if len(raw) == 4 else -1
                    if not 0 <= length <= index.chunk_end(chunk) - stream.tell():
                        msg = "a chunk whose data runs past the next record"
                        raise _Damage(msg)
                else:
                    read_chunk(stream, index, chunk)
            except (_Damage, ValueError) as err:
                return _chunk_damage(chunk, index, str(err))
    return None


def _chunk_damage(chunk: ChunkInfo, index: BagIndex, reason: str) -> str:
    """A damaged chunk in words: where, the session time it held, what --salvage does and why
    (last: what a long line loses)."""
    n = sum(chunk.counts.values())
    start = min((c.start_ns for c in index.chunks if any(c.counts.values())), default=0)
    first, last = ((t - start) / 1e9 for t in (chunk.start_ns, chunk.end_ns))
    return (
        f"the chunk at byte {chunk.pos} of {index.size} is damaged, the index intact: --salvage "
        f"skips its {n} message(s) (+{first:.1f} s to +{last:.1f} s) and reads the rest "
        f"({short(reason, 80)})"
    )


class Ros1IndexedReadBackend(_Ros1FileBackend):
    """A ROS 1 bag read through its own index when a chunk's record is damaged (rosbags, which
    reads every chunk's header to open a bag, refuses it): for ``--salvage``, which skips the
    damaged chunks (:attr:`skipped_chunks`) and reads the others. Counts and times are the
    index's (declared); messages come in log-time order as rosbags gives them."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.index: BagIndex | None = None
        self.skipped_chunks: list[SkippedChunk] = []

    def open(self) -> None:
        """Read the index (IndexDamage when it cannot be read)."""
        self.index = index = read_index(self.path)
        self.stream = self.path.open("rb")
        counts: dict[int, int] = {}
        for chunk in index.chunks:
            for conn, n in chunk.counts.items():
                counts[conn] = counts.get(conn, 0) + n
        channels: list[Channel] = []
        for c in index.connections:
            if c.conn in self._by_conn:
                continue
            channel = c.channel(len(channels), counts.get(c.conn, 0))
            channels.append(channel)
            self._by_conn[c.conn] = channel
        self.channels = tuple(channels)
        # Each chunk's times as its info or its index entries give them, a time damaged in one
        # of them left out (:func:`agreed_span`; as the reading through rosbags' index does).
        spans = entry_spans(self.stream, index)
        timed = [
            (agreed_span((c.start_ns, c.end_ns), spans.get(c.pos), widest=False), c)
            for c in index.chunks
            if any(c.counts.values())
        ]
        if timed:
            self.start_ns = min(first for (first, _), _ in timed)
            self.end_ns = max(last for (_, last), _ in timed)
        chunks = []
        for chunk in index.chunks:
            first, last = agreed_span((chunk.start_ns, chunk.end_ns), spans.get(chunk.pos))
            chunks.append(dataclasses.replace(chunk, start_ns=first, end_ns=last))
        self.index = dataclasses.replace(index, chunks=tuple(chunks))

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        assert self.stream is not None and self.index is not None
        by_conn = self._by_conn
        conns = {conn for conn, ch in by_conn.items() if topics is None or ch.topic in topics}
        for conn, time_ns, data in chunk_messages(
            self.stream, self.index, conns, self.skipped_chunks
        ):
            yield RawMessage(by_conn[conn], time_ns, data, time_ns)
