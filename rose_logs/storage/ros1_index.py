"""rosbags' ROS 1 reader, holding a message's index entry only while its chunk is being read.

rosbags' :class:`~rosbags.rosbag1.Reader` reads the index data records after every chunk when it
opens a bag and keeps an entry (time, chunk, offset) for every message, about 175 bytes each:
memory that grows with the bag (1.2 million messages: 254 MB to say what the bag holds).
:class:`LazyIndexReader` opens the bag the same way, every record read with rosbags' checks
(rosbags' own code reads the first, which gives the records' layout, and any that fails them,
for its error; the others are noted from their bytes, no entry made of each of their entries),
but keeps only, for each connection and chunk, where its index data record is, how many
entries it holds and the span of their times (five numbers in arrays: 40 bytes, less than one
entry of rosbags' even where a chunk holds a single message of the connection); a connection's
entries of a chunk are read again when its reading reaches that chunk (unpacked in one go where
the record is as noted, else by rosbags' code, for its error), and dropped once handed out. Messages come in rosbags' order (log time, then the connection's place
in the list asked for, then the chunk's place in the index, then the entry's place in its index
data), read and checked by rosbags' :meth:`~rosbags.rosbag1.Reader.messages`. Memory: the
connections, the chunk infos, five numbers per connection and chunk, and the entries of the chunks
being read (one chunk's for a recording whose chunks follow each other in time).

Relies on rosbags' internals (``read_chunk``, ``read_index_data``, ``indexes``; pinned below
0.12), as the rest of the storage layer does.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import struct
from array import array
from collections.abc import Iterator
from operator import itemgetter
from pathlib import Path
from typing import Any, cast

from rosbags.rosbag1 import Reader, ReaderError
from rosbags.rosbag1.reader import IndexData

__all__ = ["LazyIndexReader"]

_BY_TIME = itemgetter(0)  # IndexData's time (it compares by time alone, in Python: slow)
_INDEX_HEADER = 55  # bytes of an index data record before its entries (rosbags reads as many)
_UINT32 = struct.Struct("<I")
_ENTRY = struct.Struct("<III")  # an index entry: seconds, nanoseconds, offset in the chunk
_TIME = struct.Struct("<II")  # its time


class _Found(dict[int, list[IndexData]]):
    """What rosbags' ``read_index_data`` fills: the entries of a record by its connection id."""

    def __missing__(self, conn: int) -> list[IndexData]:
        listed: list[IndexData] = []
        self[conn] = listed
        return listed


class _Notes:
    """Where one connection's index entries are: a row per chunk that holds some, in the index's
    order, giving the chunk info's place in it (``k``), the number of entries (``count``), their
    earliest and latest time (``first``, ``last``, ns) and the byte offset of the index data
    record after the chunk (``at``); more records of it after that chunk (a damaged or unusual
    index, rosbags reads them all in this order) are in ``more``, by row."""

    __slots__ = ("at", "count", "first", "k", "last", "more")

    def __init__(self) -> None:
        self.k = array("q")
        self.count = array("q")
        self.first = array("q")
        self.last = array("q")
        self.at = array("q")
        self.more: dict[int, list[int]] = {}


class LazyIndexReader(Reader):
    """rosbags' ROS 1 reader (same checks, errors, messages and order) without every message's
    index entry in memory (see the module notes). ``indexes`` maps a connection id to an
    iterable of its entries in time order, read chunk by chunk as it is iterated."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self._chunk_k = -1  # the chunk info whose chunk open() read last
        self._notes: dict[int, _Notes] = {}  # by connection id

    def read_chunk(self) -> Any:
        """rosbags' reading of a chunk record's header; open() reads one per chunk info, in the
        index's order, each followed by its index data records."""
        self._chunk_k += 1
        return super().read_chunk()

    def read_index_data(self, pos: int, indexes: dict[int, list[IndexData]]) -> None:
        """The index data record where the file is (after the chunk at ``pos``) read as rosbags
        reads it (its checks and errors), noted without its entries (``indexes``, rosbags'
        lists of them, stay empty)."""
        bio = self.bio
        assert bio is not None
        at = bio.tell()
        layout = self.index_data_header_offsets  # (conn, count), rosbags' from the first record
        noted = None
        if layout is not None:
            # rosbags' checks of a record after the first, without making an entry of each of
            # its index entries (most of open()'s time where chunks hold a message or two of
            # each of many topics): its length fits its count, its bytes are there.
            head = bio.read(_INDEX_HEADER)
            if len(head) == _INDEX_HEADER:
                count = _UINT32.unpack_from(head, layout[1])[0]
                size = _UINT32.unpack_from(head, _INDEX_HEADER - 4)[0]
                body = bio.read(size) if size == 12 * count else b""
                if len(body) == size == 12 * count:
                    noted = (_UINT32.unpack_from(head, layout[0])[0], count, _span(body))
        if noted is None:  # the first record, or one rosbags' code fails on: it says what
            bio.seek(at)
            found = _Found()
            super().read_index_data(pos, found)
            ((conn, entries),) = found.items()  # one connection a record
            times = list(map(_BY_TIME, entries))
            noted = (conn, len(entries), (min(times), max(times)) if times else (0, 0))
        conn, count, (first, last) = noted
        if not count:
            return
        notes = self._notes.get(conn)
        if notes is None:
            notes = self._notes[conn] = _Notes()
        row = len(notes.k) - 1
        if row >= 0 and notes.k[row] == self._chunk_k:  # another record of it after this chunk
            notes.count[row] += count
            notes.first[row] = min(notes.first[row], first)
            notes.last[row] = max(notes.last[row], last)
            notes.more.setdefault(row, []).append(at)
            return
        notes.k.append(self._chunk_k)
        notes.count.append(count)
        notes.first.append(first)
        notes.last.append(last)
        notes.at.append(at)

    def open(self) -> None:
        """Open the bag as rosbags does (its errors), keeping where each chunk's entries are."""
        self._chunk_k = -1
        self._notes = {}
        super().open()
        # As rosbags: a connection's count is that of its index entries.
        notes = self._notes
        self.connections = [
            conn._replace(msgcount=sum(notes[conn.id].count) if conn.id in notes else 0)
            for conn in self.connections
        ]
        # rosbags' messages() only iterates them (heapq.merge), lazily.
        self.indexes = cast(
            "dict[int, list[IndexData]]",
            {conn.id: _ConnectionEntries(self, conn.id) for conn in self.connections},
        )

    def entry_spans(self, conns: set[int]) -> dict[int, tuple[int, int]]:
        """The earliest and latest time (ns) of the index entries of the connections ``conns``
        in each chunk (by its byte position) that holds some."""
        spans: dict[int, tuple[int, int]] = {}
        infos = self.chunk_infos
        for conn in conns:
            notes = self._notes.get(conn)
            if notes is None:
                continue
            for k, first, last in zip(notes.k, notes.first, notes.last, strict=True):
                pos = infos[k].pos
                was = spans.get(pos)
                spans[pos] = (
                    (first, last) if was is None else (min(was[0], first), max(was[1], last))
                )
        return spans

    def _read_entries(self, notes: _Notes, row: int) -> list[IndexData]:
        """The index entries of ``notes``' ``row`` (one connection's in one chunk), read again,
        in time order (stable: as rosbags sorts them)."""
        assert self.bio is not None
        pos = self.chunk_infos[notes.k[row]].pos
        count = notes.count[row]
        layout = self.index_data_header_offsets  # (conn, count), rosbags' from the first record
        if layout is not None and row not in notes.more:
            # One record, read and checked by rosbags' code when the bag opened: unpacked in one
            # go (rosbags' reading of it, an entry at a time, took most of the time where a
            # chunk holds a message or two of each of many topics). A record unlike what was
            # noted goes through rosbags' code below, for its error.
            self.bio.seek(notes.at[row])
            raw = self.bio.read(_INDEX_HEADER + 12 * count)
            if (
                len(raw) == _INDEX_HEADER + 12 * count
                and _UINT32.unpack_from(raw, layout[1])[0] == count
                and _UINT32.unpack_from(raw, _INDEX_HEADER - 4)[0] == 12 * count
            ):
                entries = [
                    IndexData(sec * 10**9 + nsec, pos, offset)
                    for sec, nsec, offset in _ENTRY.iter_unpack(memoryview(raw)[_INDEX_HEADER:])
                ]
                entries.sort(key=_BY_TIME)
                return entries
        found = _Found()
        for at in (notes.at[row], *notes.more.get(row, ())):
            self.bio.seek(at)
            super().read_index_data(pos, found)
        if len(found) == 1:
            (entries,) = found.values()
        else:  # the file changed under the reader (its count says so below)
            entries = [entry for listed in found.values() for entry in listed]
        if len(entries) != notes.count[row]:  # the file changed under the reader
            msg = f"the index data after the chunk at byte {pos} changed while reading"
            raise ReaderError(msg)
        entries.sort(key=_BY_TIME)
        return entries

    def entries(self, conn: int) -> Iterator[IndexData]:
        """Connection ``conn``'s index entries in rosbags' order (time, then chunk info, then
        place in the index data), each chunk's read when the first of them is due."""
        notes = self._notes.get(conn)
        if notes is None:
            return
        first, last = notes.first, notes.last
        # Rows are in the index's order: sorted stably by time, ties stay in it.
        rows = sorted(range(len(first)), key=first.__getitem__)
        if all(
            last[a] < first[b] or (last[a] == first[b] and a < b)
            for a, b in itertools.pairwise(rows)
        ):
            # Each chunk's entries all come before the next's (a recording): no merge needed.
            for row in rows:
                yield from self._read_entries(notes, row)
            return
        yield from self._merged(notes, rows)

    def _merged(self, notes: _Notes, rows: list[int]) -> Iterator[IndexData]:
        """The entries of ``notes``' ``rows`` (sorted by their first time) merged in rosbags'
        order, where chunks overlap in time: each chunk's read when its first entry is due, its
        entries handed out in runs, up to the first that another chunk's entry precedes (chunks
        that overlap at their ends only: a heap step a run, not an entry)."""
        # (time, row (the index's order), place in it (-1: the chunk's entries not read yet), what)
        queue: list[tuple[int, int, int, Any]] = [(notes.first[r], r, -1, None) for r in rows]
        heapq.heapify(queue)
        while queue:
            _, row, j, listed = queue[0]
            if j < 0:
                listed = self._read_entries(notes, row)
                heapq.heapreplace(queue, (listed[0][0], row, 0, listed))
                continue
            end = j + 1
            if len(queue) == 1:
                end = len(listed)
            elif end < len(listed):  # does the next entry come before the other chunks' next?
                other = queue[1] if len(queue) == 2 or queue[1] < queue[2] else queue[2]
                time = listed[end][0]
                if time < other[0] or (time == other[0] and row < other[1]):  # ties: index order
                    cut = bisect.bisect_right if row < other[1] else bisect.bisect_left
                    end = cut(listed, other[0], lo=end, key=_BY_TIME)
            if end == j + 1:
                yield listed[j]
            else:
                yield from itertools.islice(listed, j, end)
            if end < len(listed):
                heapq.heapreplace(queue, (listed[end][0], row, end, listed))
            else:
                heapq.heappop(queue)


def _span(entries: bytes) -> tuple[int, int]:
    """The earliest and latest time (ns) of an index data record's ``entries`` (12 bytes each:
    seconds, nanoseconds, offset), as rosbags reckons them; (0, 0) for none."""
    if len(entries) == 12:
        sec, nsec = _TIME.unpack_from(entries)
        return sec * 10**9 + nsec, sec * 10**9 + nsec
    times = [sec * 10**9 + nsec for sec, nsec, _ in _ENTRY.iter_unpack(entries)]
    return (min(times), max(times)) if times else (0, 0)


class _ConnectionEntries:
    """One connection's index entries, read as they are iterated (rosbags' ``indexes`` value:
    its messages() merges them)."""

    def __init__(self, reader: LazyIndexReader, conn: int) -> None:
        self.reader = reader
        self.conn = conn

    def __iter__(self) -> Iterator[IndexData]:
        return self.reader.entries(self.conn)
