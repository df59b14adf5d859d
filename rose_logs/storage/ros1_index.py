"""rosbags' ROS 1 reader, holding a message's index entry only while its chunk is being read.

rosbags' :class:`~rosbags.rosbag1.Reader` reads the index data records after every chunk when it
opens a bag and keeps an entry (time, chunk, offset) for every message, about 175 bytes each:
memory that grows with the bag (1.2 million messages: 254 MB to say what the bag holds).
:class:`LazyIndexReader` opens the bag the same way, every record read and checked by rosbags'
own code, but keeps only, for each index data record, where it is and the span of its times; a
connection's entries of a chunk are read again (rosbags' code too) when its reading reaches that
chunk, and dropped once handed out. Messages come in rosbags' order (log time, then the
connection's place in the list asked for, then the chunk's place in the index, then the entry's
place in its index data), read and checked by rosbags' :meth:`~rosbags.rosbag1.Reader.messages`.
Memory: the connections, the chunk infos, a few numbers per index data record, and the entries
of the chunks being read (one chunk's for a recording whose chunks follow each other in time).

Relies on rosbags' internals (``read_chunk``, ``read_index_data``, ``indexes``; pinned below
0.12), as the rest of the storage layer does.
"""

from __future__ import annotations

import heapq
import itertools
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field
from operator import itemgetter
from pathlib import Path
from typing import Any, cast

from rosbags.rosbag1 import Reader, ReaderError
from rosbags.rosbag1.reader import IndexData

__all__ = ["LazyIndexReader"]

_BY_TIME = itemgetter(0)  # IndexData's time (it compares by time alone, in Python: slow)


@dataclass
class _Entries:
    """Where the index entries of one connection in one chunk are: the index data records
    (``offsets``, bytes of the file, in the order rosbags reads them) after the chunk at byte
    ``pos``, the ``k``-th of the index's chunk infos; how many entries they hold (``count``), and
    their earliest and latest time (``first``, ``last``, ns)."""

    k: int
    pos: int
    count: int = 0
    first: int = 2**64
    last: int = -1
    offsets: list[int] = field(default_factory=list)


class LazyIndexReader(Reader):
    """rosbags' ROS 1 reader (same checks, errors, messages and order) without every message's
    index entry in memory (see the module notes). ``indexes`` maps a connection id to an
    iterable of its entries in time order, read chunk by chunk as it is iterated."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self._chunk_k = -1  # the chunk info whose chunk open() read last
        self._found: dict[tuple[int, int], _Entries] = {}  # by (chunk info, connection id)
        self.chunk_entries: dict[int, list[_Entries]] = {}  # by connection id

    def read_chunk(self) -> Any:
        """rosbags' reading of a chunk record's header; open() reads one per chunk info, in the
        index's order, each followed by its index data records."""
        self._chunk_k += 1
        return super().read_chunk()

    def read_index_data(self, pos: int, indexes: dict[int, list[IndexData]]) -> None:
        """rosbags' reading of the index data record where the file is (after the chunk at
        ``pos``), noted without its entries (``indexes``, rosbags' lists of them, stay empty)."""
        assert self.bio is not None
        at = self.bio.tell()
        found: defaultdict[int, list[IndexData]] = defaultdict(list)
        super().read_index_data(pos, found)
        ((conn, entries),) = found.items()  # one connection a record
        # A connection may have several records after a chunk (a damaged or unusual index):
        # rosbags reads them all, in this order.
        noted = self._found.setdefault((self._chunk_k, conn), _Entries(self._chunk_k, pos))
        noted.offsets.append(at)
        if entries:
            times = [entry[0] for entry in entries]
            noted.count += len(times)
            noted.first = min(noted.first, min(times))
            noted.last = max(noted.last, max(times))

    def open(self) -> None:
        """Open the bag as rosbags does (its errors), keeping where each chunk's entries are."""
        self._chunk_k = -1
        self._found = {}
        super().open()
        by_conn: dict[int, list[_Entries]] = {}
        for (_, conn), noted in self._found.items():
            if noted.count:
                by_conn.setdefault(conn, []).append(noted)
        self._found = {}
        self.chunk_entries = by_conn
        # As rosbags: a connection's count is that of its index entries.
        self.connections = [
            conn._replace(msgcount=sum(e.count for e in by_conn.get(conn.id, ())))
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
        for conn in conns:
            for e in self.chunk_entries.get(conn, ()):
                first, last = spans.get(e.pos, (e.first, e.last))
                spans[e.pos] = (min(first, e.first), max(last, e.last))
        return spans

    def _read_entries(self, chunk: _Entries) -> list[IndexData]:
        """The index entries of ``chunk`` (one connection's in one chunk), read again by
        rosbags' code, in time order (stable: as rosbags sorts them)."""
        assert self.bio is not None
        found: defaultdict[int, list[IndexData]] = defaultdict(list)
        for at in chunk.offsets:
            self.bio.seek(at)
            super().read_index_data(chunk.pos, found)
        entries = [entry for listed in found.values() for entry in listed]
        if len(entries) != chunk.count:  # the file changed under the reader
            msg = f"the index data after the chunk at byte {chunk.pos} changed while reading"
            raise ReaderError(msg)
        return sorted(entries, key=_BY_TIME)

    def entries(self, conn: int) -> Iterator[IndexData]:
        """Connection ``conn``'s index entries in rosbags' order (time, then chunk info, then
        place in the index data), each chunk's read when the first of them is due."""
        chunks = sorted(self.chunk_entries.get(conn, ()), key=lambda e: (e.first, e.k))
        if all((a.last, a.k) < (b.first, b.k) for a, b in itertools.pairwise(chunks)):
            # Each chunk's entries all come before the next's (a recording): no merge needed,
            # which cost about a microsecond an entry.
            for chunk in chunks:
                yield from self._read_entries(chunk)
            return
        # (time, chunk info, place in it (-1: the chunk's entries not read yet), what)
        queue: list[tuple[int, int, int, Any]] = [(e.first, e.k, -1, e) for e in chunks]
        heapq.heapify(queue)
        while queue:
            _, k, j, item = queue[0]
            if j < 0:
                listed = self._read_entries(item)
                heapq.heapreplace(queue, (listed[0][0], k, 0, listed))
                continue
            entry = item[j]
            if j + 1 < len(item):
                heapq.heapreplace(queue, (item[j + 1][0], k, j + 1, item))
            else:
                heapq.heappop(queue)
            yield entry


class _ConnectionEntries:
    """One connection's index entries, read as they are iterated (rosbags' ``indexes`` value:
    its messages() merges them)."""

    def __init__(self, reader: LazyIndexReader, conn: int) -> None:
        self.reader = reader
        self.conn = conn

    def __iter__(self) -> Iterator[IndexData]:
        return self.reader.entries(self.conn)
