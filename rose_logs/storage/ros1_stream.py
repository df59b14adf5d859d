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
"""

from __future__ import annotations

import bz2
import io
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from rose.limits import short
from rose_logs.storage.connections import QosStyle
from rose_logs.storage.records import Channel, RawMessage, normalize_msgtype

__all__ = ["Ros1StreamReadBackend", "unindexed_messages"]

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


@dataclass(frozen=True)
class _Connection:
    conn: int
    topic: str
    msgtype: str
    md5sum: str
    definition: str
    callerid: str | None
    latching: int | None


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


def _read_block(stream: BinaryIO, end: int, what: str) -> bytes:
    """A length-prefixed block (a record's header or data) that must end by byte ``end`` and hold
    at most :data:`_MAX_RECORD_BYTES` (checked before it is read)."""
    raw = stream.read(4)
    if len(raw) < 4:
        msg = f"the file ends inside a record's {what} length"
        raise _Damage(msg)
    (length,) = struct.unpack("<I", raw)
    if length > _MAX_RECORD_BYTES:
        msg = f"a record's {what} of {length} bytes, more than any chunk"
        raise _Damage(msg)
    if stream.tell() + length > end:
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


def _decompress(fields: dict[str, bytes], data: bytes) -> bytes:
    """A chunk's content: at most the size its header declares, so that a hostile chunk cannot
    expand without bound (a few KB of bz2 can declare gigabytes)."""
    compression = fields.get("compression", b"none").decode("ascii", "replace")
    size = _uint(fields, "size", "<I")
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
    if len(content) != size:
        msg = f"a {compression} chunk of {len(content)} bytes that declares {size}"
        raise _Damage(msg)
    return content


class Ros1StreamReadBackend:
    """A ROS 1 bag read from its start without its index (see module notes). For ``--salvage`` only.

    Attributes
    ----------
    damage : str
        Where reading stopped and why, once :meth:`open` has run.
    complete : bool
        Whether every record could be read and the index records were there (only the bag header's
        pointer to them was wrong): then nothing was lost.
    """

    profile = ""
    format = "ros1"

    def __init__(self, path: Path) -> None:
        self.path = path
        self.damage = ""
        self.complete = False
        self.channels: tuple[Channel, ...] = ()
        self._by_conn: dict[int, Channel] = {}
        self.start_ns = 0
        self.end_ns = 0
        self.qos_style: QosStyle | None = None
        self.stream: BinaryIO | None = None
        self._end: int | None = None  # where open() stopped: messages() stops there too

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
                    items: Iterator[_Connection | tuple[int, int, bytes]] = _chunk_items(content)
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
        self.complete = indexed
        if not self.damage:
            self.damage = (
                "the bag's index is damaged or misplaced; every record was read"
                if indexed
                else "no index at the end (the recording was not closed)"
            )

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
            channel = Channel(
                id=len(channels),
                topic=c.topic,
                msgtype=normalize_msgtype(c.msgtype),
                message_encoding="ros1",
                msgdef=c.definition,
                msgdef_encoding="ros1msg" if c.definition else "",
                digest=c.md5sum,
                message_count=counts.get(conn, 0),
                callerid=c.callerid,
                latching=c.latching,
            )
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

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None


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
    stream = io.BytesIO(content)
    while True:
        record = _read_record(stream, len(content))
        if record is None:
            return
        fields, data = record
        yield from _record_items(_op(fields), fields, data)


_OP_INDEX_DATA = 0x04


def unindexed_messages(path: Path, listed: dict[int, dict[int, int]]) -> str | None:
    """What the index of the ROS 1 bag ``path`` leaves out, in a few words; None when it accounts
    for every chunk and message.

    ``listed`` maps each chunk's position to the messages its chunk info counts per connection.
    The records from the bag header to the index are walked (their headers only: a chunk's data
    is skipped), and the index data records after each chunk (which locate its messages, per
    connection) are counted. A chunk info whose count was damaged, an index data record naming
    another connection, or a bag header that counts fewer chunks than the file holds, loses
    messages silently otherwise: a reader reads what the index lists.
    """
    found: dict[int, dict[int, int]] = {}
    size = path.stat().st_size
    with path.open("rb") as stream:
        stream.readline()  # the magic line (checked by whoever opened the bag)
        try:
            header = _read_record(stream, size)
            index_pos = _uint(header[0], "index_pos", "<Q") if header is not None else 0
            chunk: dict[int, int] | None = None
            while stream.tell() < index_pos:
                at = stream.tell()
                fields = _fields(_read_block(stream, index_pos, "header"))
                raw = stream.read(4)
                (length,) = struct.unpack("<I", raw) if len(raw) == 4 else (index_pos,)
                if stream.tell() + length > index_pos:
                    return f"a record at byte {at} runs past the index at byte {index_pos}"
                op = _op(fields)
                if op == _OP_CHUNK:
                    chunk = found[at] = {}
                elif op == _OP_INDEX_DATA and chunk is not None:
                    conn = _uint(fields, "conn", "<I")
                    chunk[conn] = chunk.get(conn, 0) + _uint(fields, "count", "<I")
                stream.seek(length, io.SEEK_CUR)
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
    return None


def _ids(counts: dict[int, int]) -> str:
    return ", ".join(str(conn) for conn in sorted(counts)) or "none"
